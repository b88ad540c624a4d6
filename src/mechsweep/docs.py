"""Documentation generated from the declarations: the glossary page of the documentation
(docs/glossary.md: every model's parameters, outputs, solver settings and statuses, and the status
codes) reads the ModelSpecs only, so it covers any model, built-in or a user's.

    python -m mechsweep.docs docs/glossary.md   # rewrite the page's "# Glossary" section in place
    mechsweep models --markdown                 # print the same section
    mechsweep models my_models.py:NAME --markdown   # one model's tables (a user model too)
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

HEADING = "# Glossary"
INTRO = ("Symbols, meanings and units of every parameter, output and model-specific solver setting, and the\n"
         "statuses each model's points can get (generated from the model declarations by\n"
         "`mechsweep models --markdown` or `python -m mechsweep.docs docs/glossary.md`; a test keeps this\n"
         "page in sync with the code). Units are UDUNITS-2 strings, as the datasets store them; symbols are\n"
         "written as math (the declaration's `latex` where it gives one).")


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|")  # a bare | would end the table cell


_GREEK = {"α": "alpha", "β": "beta", "γ": "gamma", "δ": "delta", "ε": "varepsilon", "ζ": "zeta", "η": "eta",
          "θ": "theta", "ϑ": "vartheta", "κ": "kappa", "λ": "lambda", "μ": "mu", "ν": "nu", "ξ": "xi", "π": "pi",
          "ρ": "rho", "σ": "sigma", "τ": "tau", "φ": "varphi", "ϕ": "phi", "χ": "chi", "ψ": "psi", "ω": "omega",
          "Γ": "Gamma", "Δ": "Delta", "Θ": "Theta", "Λ": "Lambda", "Ξ": "Xi", "Π": "Pi", "Σ": "Sigma", "Φ": "Phi",
          "Ψ": "Psi", "Ω": "Omega"}
_SCRIPTS = {"⁰": "^0", "¹": "^1", "²": "^2", "³": "^3", "⁴": "^4", "⁻¹": "^{-1}", "⁻²": "^{-2}",
            "₀": "_0", "₁": "_1", "₂": "_2", "₃": "_3", "₄": "_4"}
_FUNCTIONS = {"max": r"\max", "min": r"\min", "arg": r"\arg", "sin": r"\sin", "cos": r"\cos", "exp": r"\exp",
              "ln": r"\ln", "log": r"\log", "sign": r"\operatorname{sign}", "sqrt": r"\operatorname{sqrt}",
              "RMS": r"\mathrm{RMS}"}
_WORD = re.compile(r"[A-Za-z]{4,}")
_SUBSCRIPT = re.compile(r"_([A-Za-z0-9,]+|[^\sA-Za-z0-9])")


def _index(text: str, i: int, out: list) -> int:
    """Digits right after a one-letter symbol are its index (``λ1``, ``A0``, ``f3``): a subscript."""
    m = re.compile(r"\d+").match(text, i)
    if m:
        out[-1] = out[-1].rstrip() + "_{" + m.group(0) + "}"
        return m.end()
    return i


def symbol_math(symbol: str, latex: str = "") -> str:
    """A declaration's symbol as the glossary shows it: ``latex`` (the declaration's own LaTeX, when
    it has one) or the symbol written as math, e.g. ``ε = μ A² / ω²`` -> ``$\\varepsilon = \\mu A^2 /
    \\omega^2$``, ``v_max`` -> ``$v_{\\mathrm{max}}$``; a symbol that is words rather than a formula
    (``stable (Floquet)``) stays text, and ``-`` stands for none."""
    if latex:
        return "$" + latex.strip().strip("$").replace("|", r"\vert ") + "$"
    if not symbol:
        return "-"
    if any(w not in _FUNCTIONS for w in _WORD.findall(re.sub(r"_[A-Za-z0-9,]+", "", symbol))):
        return _cell(symbol)  # words, not a formula
    text = symbol
    for k in sorted(_SCRIPTS, key=len, reverse=True):
        text = text.replace(k, _SCRIPTS[k])
    out, i = [], 0
    while i < len(text):
        c = text[i]
        sub = _SUBSCRIPT.match(text, i) if c == "_" else None
        word = re.compile(r"[A-Za-z]+").match(text, i)
        if sub:  # one character as it is, a longer subscript upright
            body = sub.group(1)
            body = "\\" + _GREEK[body] if body in _GREEK else body
            out.append("_{" + (body if len(sub.group(1)) == 1 else r"\mathrm{" + body + "}") + "}")
            i = sub.end()
        elif word:
            w = word.group(0)
            out.append(_FUNCTIONS[w] + " " if w in _FUNCTIONS else w if len(w) == 1 else r"\mathit{" + w + "}")
            i = word.end()
            i = _index(text, i, out) if len(w) == 1 else i
        else:
            if c in _GREEK:
                out.append("\\" + _GREEK[c] + " ")
                i = _index(text, i + 1, out) - 1
            elif c == "|":
                out.append(r"\vert ")
            elif c == " ":
                prev, nxt = text[i - 1:i], text[i + 1:i + 2]
                out.append(r"\," if (prev.isalnum() or prev == "}") and (nxt.isalnum() or nxt in _GREEK) else " ")
            else:
                out.append(c)
            i += 1
    return "$" + re.sub(r" +", " ", "".join(out)).strip() + "$"


def _unit(unit: str) -> str:
    return f"`{unit}`" if unit else "(not declared)"


def status_table() -> str:
    """The status codes and their generic meaning (status.py)."""
    from . import status as st

    lines = ["## Status codes", "", "| code | status | meaning |", "|---|---|---|"]
    for code in sorted(st.MEANINGS):
        lines.append(f"| {code} | `{st.MEANINGS[code]}` | {_cell(st.DESCRIPTIONS[code])} |")
    return "\n".join(lines) + "\n"


def model_markdown(spec) -> str:
    """Glossary tables of one model: parameters, outputs, methods, settings, statuses."""
    from . import status as st

    lines = [f"## `{spec.name}`: {spec.description}", "", f"Source: {spec.source}.", ""]
    if spec.references:
        lines += ["References: " + "; ".join(spec.references) + ".", ""]
    lines += [
             "| parameter | symbol | meaning | unit | allowed |", "|---|---|---|---|---|"]
    for p in spec.params:
        opt = " (optional)" if not p.required else ""
        opt += (f" (a scene may also call it {', '.join(f'`{a}`' for a in p.aliases)}, its former name; datasets "
                f"name it `{p.name}`)" if p.aliases else "")
        lines.append(f"| `{p.name}` | {symbol_math(p.symbol, getattr(p, 'latex', ''))} | {_cell(p.long_name)}{opt} | "
                     f"{_unit(p.unit)} | {p.allowed()} |")
    lines += ["", "| output | symbol | meaning | unit |", "|---|---|---|---|"]
    for o in spec.outputs:
        how = " (integrated)" if o.integrated else ""
        how += f" (per {', '.join(d.name for d in o.extra_dims)})" if o.extra_dims else ""
        lines.append(f"| `{o.name}` | {symbol_math(o.symbol, getattr(o, 'latex', ''))} | {_cell(o.long_name)}{how} | "
                     f"{_unit(o.unit)} |")
    if any(o.integrated for o in spec.outputs):
        lines += ["", "`solver.method`: " + ", ".join(f"`{m}`" for m in spec.methods) + " (default `dop853`)."]
    if spec.settings:
        lines += ["", "| solver setting | meaning | unit | default | allowed |", "|---|---|---|---|---|"]
        for s in spec.settings:
            lines.append(f"| `{s.name}` | {_cell(s.long_name)} | {_unit(s.unit)} | {s.default:g} | [{s.lo:g}, {s.hi:g}] |")
    codes = spec.possible_statuses()
    how = "declared, and those its outputs imply" if spec.statuses else "derived from its outputs"
    lines += ["", f"Statuses ({how}): " + ", ".join(f"`{st.MEANINGS.get(c, c)}`" for c in codes) + "."]
    if spec.status_notes:
        lines += ["", "| status | for this model |", "|---|---|"]
        lines += [f"| `{st.MEANINGS.get(c, c)}` | {_cell(t)} |" for c, t in spec.status_notes]
    return "\n".join(lines) + "\n"


def glossary(specs=None) -> str:
    """The glossary page: the status codes, then every model of ``specs`` (default:
    the built-in models, in their table's order)."""
    if specs is None:
        from .models import MODELS

        specs = MODELS.values()
    parts = [f"{HEADING}\n\n{INTRO}\n", status_table()] + [model_markdown(s) for s in specs]
    return "\n".join(parts)


def glossary_section(text: str) -> str:
    """The generated section of a page's text, from its "# Glossary" heading to the next level-1
    heading or the end ("" when there is none)."""
    start = 0 if text.startswith(f"{HEADING}\n") else text.find(f"\n{HEADING}\n") + 1
    if start == 0 and not text.startswith(f"{HEADING}\n"):
        return ""
    end = text.find("\n# ", start + len(HEADING))
    return text[start:] if end < 0 else text[start:end + 1]


def write_page(path: str | Path) -> bool:
    """Replace the glossary section of the page at ``path`` by the generated one; True if changed."""
    path = Path(path)
    text = path.read_text()
    old = glossary_section(text)
    if not old:
        raise SystemExit(f"{path} has no '{HEADING}' section")
    new = glossary()
    if old.endswith("\n\n") and not new.endswith("\n\n"):
        new += "\n"  # keep the blank line before the next section
    if old == new:
        return False
    path.write_text(text.replace(old, new, 1))
    return True


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: python -m mechsweep.docs docs/glossary.md", file=sys.stderr)
        sys.exit(2)
    print(f"{sys.argv[1]}: {'rewritten' if write_page(sys.argv[1]) else 'already up to date'}")
