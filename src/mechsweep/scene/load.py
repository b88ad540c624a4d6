"""Reading a scene: a TOML file (read with care: it may be anything a user names), TOML text or a
dict with the same structure, checked section by section (:func:`~.sections.validate`) into a
frozen :class:`~.spec.Scene`; and a scene dict written back as TOML (:func:`to_toml`)."""
from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import file_kind
from .sections import validate
from .spec import Scene, SceneError
from .text import unstorable_in

MAX_KEY_DEPTH = 32  # dotted keys a.b.c...: tomllib's time grows with the square of the depth
_DEEP_KEY = re.compile(r"(?<![A-Za-z0-9_-])(?:(?:[A-Za-z0-9_-]++|\"[^\"\n]*+\"|'[^'\n]*+')[ \t]*+\.[ \t]*+)"
                       + "{" + str(MAX_KEY_DEPTH) + ",}")


def load_scene(source: str | Path | Mapping, models: Mapping | None = None) -> Scene:
    """Load and validate a scene from a TOML file or a dict with the same structure.

    Every problem is collected and reported at once; nothing runs and nothing is written.

    Parameters
    ----------
    source : str, pathlib.Path or Mapping
        The scene file's path, or a dict with its sections (``{"scene": {...}, "axes": {...},
        ...}``). A model file named in a file's ``[scene] model`` is relative to the file's folder;
        in a dict, to the working directory.
    models : Mapping, optional
        Model name -> :class:`~mechsweep.model.OdeModel` (or a ``ModelSpec``) defined in Python,
        for a scene whose ``model`` is that name.

    Returns
    -------
    Scene
        The validated, frozen scene.

    Raises
    ------
    SceneError
        The scene is not valid: its ``problems`` list one message per bad key, each naming the
        key, the bad value and what is allowed.
    """
    if isinstance(source, Mapping):
        source = _plain(source)
        if (why := unstorable_in(source)) is not None:
            raise SceneError([why], "scene")
        text = to_toml(source)
        if len(text) > MAX_SCENE_BYTES:
            raise SceneError([f"the scene's TOML form is {_mib(len(text))}; a scene is at most "
                              f"{_mib(MAX_SCENE_BYTES)} ({SCENE_TOO_BIG_ADVICE})"], "scene")
        return validate(source, text=text, label="scene", models=models)
    path = Path(source)
    label = str(path)
    raw = read_scene_file(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError([f"{label!r} is not UTF-8 text (byte {exc.start})"], label) from None
    return load_scene_text(text, label, base=path.resolve().parent, models=models)


# A scene is a page of TOML: a few kB, and a list axis of a million values is about 13 MiB (about 3 s
# to parse). Nothing beyond this is read: a device, a dataset or a log given as the scene by mistake
# is refused before its bytes fill the memory.
MAX_SCENE_BYTES = 16 * 2**20
SCENE_TOO_BIG_ADVICE = "give a long axis as a range { start, stop, num }, not as a list of values"


def _mib(n: int) -> str:
    return f"{n / 2**20:.3g} MiB" if n >= 2**20 else f"{n:,} bytes"


def read_scene_file(path: Path) -> bytes:
    """The bytes of the scene file ``path``: a regular file of at most MAX_SCENE_BYTES. A folder,
    a pipe, a socket or a device is refused without reading it (a pipe nobody writes would block,
    /dev/zero never ends), as is a larger file; every refusal names what the path is."""
    import errno
    import os
    import stat

    label = str(path)

    def refuse(why: str):
        raise SceneError([why], "scene")

    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if os.path.islink(path):
            refuse(f"{label!r} is a broken symbolic link (to {os.readlink(path)!r}); a scene is a TOML file")
        refuse(f"file {label!r} does not exist")
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            refuse(f"{label!r} is a symbolic link loop (it leads back to itself); a scene is a TOML file")
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    if stat.S_ISDIR(mode):
        refuse(f"{label!r} is a directory, not a scene file")
    if not stat.S_ISREG(mode):
        refuse(f"{label!r} is {file_kind(mode)}, not a scene file; a scene is a regular TOML file")
    try:  # O_NONBLOCK: should the path have become a pipe since, the open does not wait for a writer
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            refuse(f"{label!r} is {file_kind(info.st_mode)}, not a scene file; a scene is a regular TOML file")
        if info.st_size > MAX_SCENE_BYTES:
            refuse(f"{label!r} is {_mib(info.st_size)}; a scene file is at most {_mib(MAX_SCENE_BYTES)} "
                   f"({SCENE_TOO_BIG_ADVICE}); is it a scene?")
        parts, size = [], 0
        while size <= MAX_SCENE_BYTES:  # a file that grows, or that says it is empty (/proc), is read up to the cap
            block = os.read(fd, min(2**20, MAX_SCENE_BYTES + 1 - size))
            if not block:
                break
            parts.append(block)
            size += len(block)
        if size > MAX_SCENE_BYTES:
            refuse(f"{label!r} holds more than {_mib(MAX_SCENE_BYTES)}; a scene file is at most that "
                   f"({SCENE_TOO_BIG_ADVICE}); is it a scene?")
        return b"".join(parts)
    except OSError as exc:
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    finally:
        os.close(fd)


def _os_reason(exc: OSError) -> str:
    from ..errors import why_os_error

    return why_os_error(exc.errno, exc.strerror or str(exc))


def _plain(value):
    """A scene dict with numpy scalars and arrays made plain Python values (np.float64(2.0) is a
    number, like 2.0), as a TOML file would give them."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.ndim else _plain(value.item())
    if isinstance(value, np.generic):
        return value.item()
    return value


def load_scene_text(text: str, label: str = "scene", base: Path | str | None = None,
                    models: Mapping | None = None) -> Scene:
    """Load and validate a scene from its TOML text (e.g. the copy stored with a run).
    ``base``: the folder a user model file path ("my_models.py:NAME") is relative to (default: cwd)."""
    if len(text) > MAX_SCENE_BYTES:  # e.g. the scene text stored in a dataset someone made or edited
        raise SceneError([f"{label!r}: the scene text is {_mib(len(text))}; a scene is at most "
                          f"{_mib(MAX_SCENE_BYTES)} ({SCENE_TOO_BIG_ADVICE})"], label)
    if text.startswith("\ufeff"):
        raise SceneError([(f"{label!r} starts with a byte-order mark (BOM, bytes EF BB BF); "
                           "save it as UTF-8 without BOM")], label)
    deep = _DEEP_KEY.search(text)
    if deep:
        line = text.count("\n", 0, deep.start()) + 1
        raise SceneError([(f"TOML nesting too deep: a dotted key at line {line} has more than {MAX_KEY_DEPTH} "
                           "levels")], label)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError([f"TOML syntax error: {exc}"], label) from None
    except RecursionError:
        raise SceneError(["TOML nesting too deep"], label) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise SceneError([f"TOML value not readable ({str(exc).split(';')[0]})"], label) from None
    return validate(data, text=text, label=label, base=base, models=models)


# ----------------------------------------------------------------------------- dict -> TOML
def to_toml(data: Mapping) -> str:
    """Write a scene dict as TOML (the subset scenes use), so a dict scene is stored as text too."""
    lines = []
    for section, table in data.items():
        if not isinstance(table, Mapping):
            lines.append(f"{_key(section)} = {_value(table)}")
            continue
        lines.append(f"[{_key(section)}]")
        lines.extend(f"{_key(k)} = {_value(v)}" for k, v in table.items())
        lines.append("")
    return "\n".join(lines)


def _key(k) -> str:
    k = str(k)
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return json.dumps(str(v))
