"""The shipped scenes the benchmarks draw their samples from, as package data: copies of
``sweeps/<name>.toml`` (a test keeps them byte-identical), so that `mechsweep bench` works from an
installed package, where the repository's ``sweeps/`` folder does not exist."""
from __future__ import annotations

from importlib import resources
from pathlib import Path


def path(name: str) -> Path:
    """The packaged scene ``name`` (a file name such as ``duffing_amplitude_period.toml``)."""
    found = resources.files(__name__).joinpath(name)
    if not found.is_file():
        raise FileNotFoundError(f"no packaged bench scene {name!r} in {resources.files(__name__)}")
    return Path(str(found))


def names() -> tuple[str, ...]:
    """Every packaged scene's file name."""
    return tuple(sorted(p.name for p in resources.files(__name__).iterdir() if p.name.endswith(".toml")))
