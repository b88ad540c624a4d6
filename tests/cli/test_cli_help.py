"""Every subcommand's --help teaches: a description of what it does, help for each argument and
option, and an example command line (for `plot`, what -o writes, as figures.targets writes it)."""
from __future__ import annotations

import argparse
import re

import pytest

from mechsweep import cli


def _subcommands(parser, prefix=("mechsweep",)):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield prefix + (name,), sub
                yield from _subcommands(sub, prefix + (name,))


SUBCOMMANDS = dict(_subcommands(cli._parser()))


def test_every_command_is_listed():
    names = {" ".join(k[1:]) for k in SUBCOMMANDS}
    assert {"run", "plot", "info", "models", "boundaries", "check", "bench", "bench duffing",
            "bench workprecision"} <= names, names


@pytest.mark.parametrize("path", sorted(SUBCOMMANDS), ids=lambda p: " ".join(p[1:]))
def test_help_has_a_description_every_option_explained_and_an_example(path):
    sub = SUBCOMMANDS[path]
    text = sub.format_help()
    assert sub.description and len(sub.description.split()) >= 8, (path, sub.description)
    for action in sub._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        assert action.help and len(action.help.split()) >= 2, (path, action.option_strings or action.dest)
    examples = re.search(r"^examples?:\n((?:  .+\n?)+)", text, re.M)
    assert examples, f"{' '.join(path)} --help shows no example:\n{text}"
    assert " ".join(path) in examples.group(1), (path, examples.group(1))


def test_plot_help_says_where_the_figures_go_as_they_do(tmp_path, monkeypatch):
    """The -o lines of `plot --help` against figures.targets: one figure -> the file itself,
    several -> FIGURE_<figure>.<fmt> beside it."""
    from mechsweep import figures

    text = SUBCOMMANDS[("mechsweep", "plot")].format_help()
    assert "-o FIGURE.png    that file for one figure; for several, FIGURE_<figure>.png beside it" in text
    assert "NAME.png for one figure, NAME_<figure>.png for each of" in text

    class Two:  # a dataset with two figures, as far as targets is concerned
        pass

    kinds = {"amplitude_period": "", "kinematic_coefficients": ""}
    monkeypatch.setattr(figures, "available", lambda ds, axes=None: kinds)
    assert figures.targets(Two(), tmp_path / "FIGURE.png") == [tmp_path / "FIGURE_amplitude_period.png",
                                                              tmp_path / "FIGURE_kinematic_coefficients.png"]
    assert figures.targets(Two(), tmp_path / "FIGURE.png", kind="amplitude_period") == [tmp_path / "FIGURE.png"]
