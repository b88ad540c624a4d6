"""Reading datasets works where the POSIX modules ``fcntl`` and ``resource`` do not exist (Windows):
a fresh interpreter in which importing them fails (``sys.modules`` entries set to None) opens a
dataset with ``mechsweep.open_dataset``, describes it with ``mechsweep info`` and draws it with
``mechsweep plot``; ``mechsweep run`` there is refused in one line naming the systems that run sweeps."""
from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import SWEEPS

NO_POSIX = "import sys\nsys.modules['fcntl'] = None\nsys.modules['resource'] = None\n"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    import mechsweep

    folder = tmp_path_factory.mktemp("platforms")
    scene = {"scene": {"name": "p", "model": "duffing", "outputs": ["period_exact", "kv"]},
             "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 4}, "mu": {"start": 0.1, "stop": 10.0, "num": 3}},
             "fixed": {"omega": 2.0}}
    mechsweep.run(scene, output=folder / "p.h5", progress=False)
    return folder / "p.h5"


def _python(code: str, cwd):
    return subprocess.run([sys.executable, "-c", NO_POSIX + code], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_the_simulation_hides_the_modules(tmp_path):
    out = _python("import importlib\nfor m in ('fcntl', 'resource'):\n"
                  "    try:\n        importlib.import_module(m)\n    except ImportError:\n        print('no', m)\n",
                  tmp_path)
    assert out.stdout.split("\n")[:2] == ["no fcntl", "no resource"], out.stderr


def test_datasets_open_and_plot_without_fcntl_and_resource(dataset, tmp_path):
    code = (f"import mechsweep\nds = mechsweep.open_dataset({str(dataset)!r})\n"
            "print('opened', dict(ds.sizes))\n"
            "from mechsweep import cli\n"
            f"print('info', cli.main(['info', {str(dataset)!r}]))\n"
            f"print('plot', cli.main(['plot', {str(dataset)!r}, '-o', 'fig.png']))\n"
            "assert 'fcntl' not in sys.modules or sys.modules['fcntl'] is None\n")
    out = _python(code, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "opened {'A': 4, 'mu': 3}" in out.stdout and "info 0" in out.stdout and "plot 0" in out.stdout, out.stdout
    assert list(tmp_path.glob("*.png")), out.stdout


def test_a_run_without_file_locks_is_refused_in_one_line(tmp_path):
    code = ("from mechsweep import cli\n"
            f"sys.exit(cli.main(['run', {str(SWEEPS / 'quickstart.toml')!r}, '-o', 'q.h5']))\n")
    out = _python(code, tmp_path)
    assert out.returncode == 2, (out.stdout, out.stderr[-3000:])
    assert "Traceback" not in out.stderr and "sweeps run on Linux and macOS" in out.stderr, out.stderr
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())
