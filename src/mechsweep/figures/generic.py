"""Fallback figures for any dataset: lines over one axis, maps over two."""
from __future__ import annotations


from ._style import flag_note, label, log_or_symlog, new_figure, ok_values, title


def _numeric_dims(ds):
    return [d for d in ds.dims if ds[d].dtype.kind in "fiu" and ds.sizes[d] > 1]


def can_outputs(ds) -> bool:
    return 1 <= len(_numeric_dims(ds)) <= 2 and bool(ds.attrs.get("outputs"))


def outputs(ds):
    """Each output against the first axis (lines, one per value of a second axis) ."""
    names = ds.attrs["outputs"].split()
    dims = _numeric_dims(ds)
    x = dims[-1]
    fig, axes = new_figure(len(names), 1, width=6.4, height=3.0)
    for r, name in enumerate(names):
        ax = axes[r, 0]
        da = ok_values(ds, name)
        rest = [d for d in da.dims if d != x]
        flat = da.transpose(*rest, x).values.reshape(-1, ds.sizes[x]) if rest else da.values[None, :]
        step = max(1, flat.shape[0] // 12)
        for row in flat[::step]:
            ax.plot(ds[x].values, row, lw=1.0)
        log_or_symlog(ax, ds[x].values)
        ax.set_xlabel(label(ds[x]))
        ax.set_ylabel(label(ds[name]))
        ax.grid(True, alpha=0.3)
        flag_note(ax, ds)
    title(fig, ds, "Outputs")
    return fig
