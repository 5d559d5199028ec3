"""The basin cache on disk (cartpole.validation.basin.BasinCache.on_disk) trusts no file by its name: a file whose
content is not the one recorded when it was saved, or one holding values no estimate can have (a negative or NaN
rho), is discarded and the basin estimated again; a basins directory others may write to is refused."""
import io

import numpy as np
import pytest

from cartpole import codegen
from cartpole.validation.basin import BasinCache, plausible

KW = {"n": 40, "duration": 1.0}


@pytest.fixture
def stored(tmp_path):
    first = BasinCache.on_disk(tmp_path / "basins")
    est = first.get(None, **KW)
    assert first.misses == 1
    [path] = (tmp_path / "basins").glob("*.npz")
    return tmp_path / "basins", path, est


def test_a_stored_estimate_is_found_again_by_another_cache(stored):
    directory, _, est = stored
    again = BasinCache.on_disk(directory)
    assert again.get(None, **KW).rho == est.rho and again.hits == 1 and again.misses == 0


def _rewrite(path, old_rho, rho):
    """The stored file's bytes with its rho (found by value among the stored scalars) replaced."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: np.array(z[k]) for k in z.files}
    [i] = np.flatnonzero(arrays["scalars"] == old_rho)[:1]
    arrays["scalars"][i] = rho
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@pytest.mark.parametrize("rho", [-1.0, float("nan")])
def test_a_file_with_impossible_values_is_discarded_and_estimated_again(stored, rho):
    directory, path, est = stored
    codegen.write_verified(path, _rewrite(path, est.rho, rho))  # a correct hash of wrong values
    again = BasinCache.on_disk(directory)
    got = again.get(None, **KW)
    assert again.misses == 1 and got.rho == est.rho and plausible(got)
    assert BasinCache.on_disk(directory).get(None, **KW).rho == est.rho  # and the good estimate stored again


def test_a_file_that_is_not_what_was_saved_is_estimated_again(stored):
    directory, path, est = stored
    path.write_bytes(_rewrite(path, est.rho, est.rho * 10))  # a plausible-looking level, but not the content recorded
    again = BasinCache.on_disk(directory)
    assert again.get(None, **KW).rho == est.rho and again.misses == 1


def test_a_basins_directory_others_may_write_to_is_refused(tmp_path):
    d = tmp_path / "basins"
    d.mkdir()
    d.chmod(0o777)
    with pytest.raises(codegen.CacheError):
        BasinCache.on_disk(d).get(None, **KW)
