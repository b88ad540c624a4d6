"""Opt-in (python -m pytest -m slow): every shipped scene at full size, checked for its promises."""
import numpy as np
import pytest

import mechsweep
from mechsweep import status as st

from .conftest import SWEEPS

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("path", sorted(SWEEPS.glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_scene_full_size(in_tmp, path):
    scene = mechsweep.load_scene(path)
    ds = mechsweep.run(scene, output=in_tmp / "data" / "runs" / f"{path.stem}.h5", progress=False)
    ok = ds["status"].values == st.OK
    assert ok.any()
    assert not (ds["status"].values == st.PENDING).any()
    for name in scene.outputs:
        values = ds[name].values
        # never a NaN or inf with status ok (a flagged point may keep what could be computed)
        assert np.isfinite(values[ok]).all(), name
    if "period_error" in ds:
        assert float(ds["period_error"].max()) <= 1e-10 * 1.0001  # promised at rtol 1e-10
