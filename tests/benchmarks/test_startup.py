"""benchmarks/startup.py: the fixed costs and cold start of a run; its options are checked first."""
import os

import mechsweep
from benchmarks import startup


def test_bench_startup_refuses_fewer_than_three_repeats(capsys):
    assert startup.cli(["--repeats", "2", "--only", "warm"]) == 2
    assert "--repeats = 2 is not allowed; expected a whole number in [3, 100]" in capsys.readouterr().err


def test_bench_startup_against_needs_a_package_folder_and_warmstart(capsys, tmp_path):
    assert startup.cli(["--only", "warmstart", "--against", str(tmp_path)]) == 2
    assert f"--against {tmp_path}: no mechsweep package in it" in capsys.readouterr().err
    src = os.path.dirname(os.path.dirname(os.path.abspath(mechsweep.__file__)))
    assert startup.cli(["--only", "warm", "--against", src]) == 2
    assert "--against applies to --only warmstart only" in capsys.readouterr().err
