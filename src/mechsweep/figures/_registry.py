"""How a figure module declares the figures it draws for a model, so that the figure package's
front (``figures/__init__.py``) chooses figures from a dataset's attributes alone and names no model
and no variable."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable


@dataclass(frozen=True)
class ModelFigure:
    """A figure drawn for one model (or one kind of benchmark dataset).

    It fits a dataset whose ``model`` attribute is one of ``models`` (or whose ``mechsweep_kind``
    attribute is one of ``dataset_kinds``), that holds every output in ``needs`` and at least one
    of ``any_of`` (when given), and for which ``fits(ds)`` (when given: conditions on dimensions)
    is true. ``draws`` lists every output the figure shows: the generic figures leave them to it.
    ``draw(ds)`` returns a matplotlib Figure; the first paragraph of its docstring describes it.
    With ``boundaries`` true it is called ``draw(ds, boundaries=BDS)``: BDS is the located boundaries
    dataset of the same grid (``mechsweep boundaries``), or None, and is drawn over the chart.
    """

    name: str
    draw: Callable = field(repr=False)
    models: tuple[str, ...] = ()
    dataset_kinds: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()
    any_of: tuple[str, ...] = ()
    draws: tuple[str, ...] = ()
    fits: Callable | None = field(default=None, repr=False)
    boundaries: bool = False

    def fits_dataset(self, ds) -> bool:
        attrs = ds.attrs
        if not (attrs.get("model") in self.models or attrs.get("mechsweep_kind") in self.dataset_kinds):
            return False
        if not all(n in ds.data_vars for n in self.needs):
            return False
        if self.any_of and not any(n in ds.data_vars for n in self.any_of):
            return False
        return self.fits is None or bool(self.fits(ds))

    def drawn(self, ds) -> set[str]:
        """The outputs of ``ds`` this figure shows."""
        return {n for n in self.needs + self.any_of + self.draws if n in ds.data_vars}

    @property
    def description(self) -> str:
        return describe(self.draw)


def describe(fn) -> str:
    """The first paragraph of a function's docstring, on one line (never cut mid-sentence)."""
    doc = (fn.__doc__ or "").strip()
    return " ".join(doc.split("\n\n")[0].split())
