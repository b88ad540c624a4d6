"""Whether a text is mathtext matplotlib's parser reads: the figures' labels (figures/_style.py) and
the check of a model's declared ``latex`` at loading (model/user.py), which must not import the
figures package (it imports the boundaries, the runner...: an import circle)."""
from __future__ import annotations


def latex_problem(text) -> str | None:
    """Why a declared ``latex`` string cannot label a figure (None: it can): it must hold
    mathtext (between ``$`` signs) that matplotlib's parser reads."""
    from matplotlib.cbook import is_math_text

    text = str(text)
    if "\n" in text or not is_math_text(text):
        return "it is not mathtext between $ signs (one line), e.g. '$\\omega_0$'"
    if not _parses(text):
        return "matplotlib's mathtext parser cannot read it"
    return None


_PARSED: dict[str, bool] = {}


def _parses(text: str) -> bool:
    """Whether matplotlib's mathtext parses ``text`` (cached)."""
    if text not in _PARSED:
        from matplotlib.font_manager import FontProperties
        from matplotlib.mathtext import MathTextParser

        try:
            MathTextParser("path").parse(text, 72, FontProperties())
            _PARSED[text] = True
        except Exception:  # noqa: BLE001 (any parse failure: the label goes without mathtext)
            _PARSED[text] = False
    return _PARSED[text]
