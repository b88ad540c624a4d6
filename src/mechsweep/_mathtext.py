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
    """Whether matplotlib's mathtext parses ``text`` (cached): each of its math spans, each span
    parsed once however many labels hold it (a figure's labels repeat their symbols: the axis
    label, the legend, the caption); the whole text when its spans cannot be told by splitting it
    at its dollar signs (see :func:`_spans`)."""
    spans = _spans(text)
    return _parsed(text) if spans is None else all(_parsed(span) for span in spans)


def _spans(text: str) -> list[str] | None:
    """The math spans of one line of mathtext, each with its dollar signs, when the line parses
    exactly when each of them does, else None. Matplotlib's parser reads a line as text, a math span
    (from a ``$`` to the next one not escaped by a backslash), text, and so on to the end; the text
    in between is drawn as it is (its characters never fail to parse), and each span is parsed
    alone from the same state (the text's font never leaks into it). Only a line with an even
    number of dollar signs, none after a backslash (an escaped ``\\$``, or a backslash escaping
    another inside a span), and no line break is split here."""
    if "\n" in text or "\\$" in text:
        return None
    parts = text.split("$")
    if len(parts) < 3 or len(parts) % 2 == 0:
        return None
    return [f"${body}$" for body in parts[1::2]]


def _parsed(text: str) -> bool:
    """Whether matplotlib's mathtext parses ``text`` as a whole (cached)."""
    if text not in _PARSED:
        from matplotlib.font_manager import FontProperties
        from matplotlib.mathtext import MathTextParser

        try:
            MathTextParser("path").parse(text, 72, FontProperties())
            _PARSED[text] = True
        except Exception:  # noqa: BLE001 (any parse failure: the label goes without mathtext)
            _PARSED[text] = False
    return _PARSED[text]
