"""vcnc_agents.model_file: a model.zip whose members inflate beyond the documented ceilings is refused before
anything is inflated."""

from __future__ import annotations

import time
import zipfile

import pytest

from vcnc_agents.model_file import MAX_DATA_BYTES, read_model_data


def _bomb(path, name: str, size: int) -> None:
    """A zip whose member ``name`` inflates to ``size`` zero bytes (a few kB on disk per 4 MB)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        info = zipfile.ZipInfo(name)
        info.compress_type = zipfile.ZIP_DEFLATED
        with z.open(info, "w", force_zip64=True) as f:
            chunk = b"\0" * (1 << 20)
            for _ in range(size >> 20):
                f.write(chunk)
        z.writestr("policy.pth" if name == "data" else "data", b"{}")


@pytest.mark.parametrize("name", ["data", pytest.param("policy.pth", marks=pytest.mark.slow)])  # 257 MB deflated: 6 s
def test_a_member_inflating_beyond_its_ceiling_is_refused_before_it_is_inflated(tmp_path, name):
    path = tmp_path / "model.zip"
    size = (MAX_DATA_BYTES if name == "data" else 256 * 1024**2) + (1 << 20)
    _bomb(path, name, size)
    assert path.stat().st_size < size / 100  # a bomb
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=f"member '{name}' inflates to"):
        read_model_data(path)
    assert time.perf_counter() - t0 < 1.0
