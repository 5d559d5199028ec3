import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).parent))

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
