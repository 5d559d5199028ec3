import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).parent))

from chains import CHAINS, write_chain  # noqa: E402
from variants import VARIANTS, write_variant  # noqa: E402


@pytest.fixture(scope="session")
def variant_dir(tmp_path_factory):
    """A directory holding every MJCF variant (written once per session)."""
    d = tmp_path_factory.mktemp("variants")
    for name in VARIANTS:
        write_variant(d, name)
    return d


@pytest.fixture(params=["shipped", *VARIANTS])
def any_mjcf(request, variant_dir):
    """The shipped asset and each variant's path, one test per model."""
    if request.param == "shipped":
        from cartpole.models import SHIPPED_MJCF
        return SHIPPED_MJCF
    return variant_dir / f"cartpole_{request.param}.xml"


@pytest.fixture(scope="session")
def chain_dir(tmp_path_factory):
    """A directory holding every MJCF of the chain family (tests/chains.py), written once per session."""
    d = tmp_path_factory.mktemp("chains")
    for name in CHAINS:
        write_chain(d, name)
    return d


@pytest.fixture(params=["shipped", "two_pole", "three_pole", *VARIANTS, *CHAINS])
def family_mjcf(request, variant_dir, chain_dir):
    """Every model shape the reader accepts: the shipped assets, the single-pole variants and the chains."""
    from cartpole.models import SHIPPED_MJCF
    if request.param == "shipped":
        return SHIPPED_MJCF
    if request.param in ("two_pole", "three_pole"):
        return SHIPPED_MJCF.with_name(f"cartpole_{request.param}.xml")
    if request.param in VARIANTS:
        return variant_dir / f"cartpole_{request.param}.xml"
    return chain_dir / f"{request.param}.xml"
