import os
import random
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).parent))

from chains import CHAINS, write_chain  # noqa: E402
from variants import VARIANTS, write_variant  # noqa: E402


# ---- hypothesis: randomised, its seed printed so that a failure reproduces with one environment variable ---------
# Every run draws fresh examples from one seed: --hypothesis-seed, else $HYPOTHESIS_SEED, else a new random one. The
# controller picks it and hands it to the xdist workers, hypothesis' own plugin applies it (each test then draws from
# that seed, whatever runs beside it), and the header (without -q) and the summary (always) print it. No example
# database: a failure found once is kept as an explicit @example in the test module, not in a local cache.
SEED_VARIABLE = "HYPOTHESIS_SEED"

try:
    from hypothesis import settings as _hypothesis_settings
except ImportError:  # the property tests skip without the dev extra
    _hypothesis_settings = None
else:
    _hypothesis_settings.register_profile("cartpole", derandomize=False, database=None)
    _hypothesis_settings.load_profile("cartpole")


def _hypothesis_seed(config):
    """The seed of this run (a decimal string), or None without hypothesis."""
    if _hypothesis_settings is None:
        return None
    if hasattr(config, "workerinput"):  # an xdist worker: the controller's seed
        return config.workerinput.get("hypothesis_seed")
    return (config.getoption("hypothesis_seed", None) or os.environ.get(SEED_VARIABLE)
            or str(random.SystemRandom().randrange(2**32)))


@pytest.hookimpl(tryfirst=True)  # before hypothesis' plugin reads --hypothesis-seed in its own pytest_configure
def pytest_configure(config):
    seed = _hypothesis_seed(config)
    if seed is not None:
        config.option.hypothesis_seed = seed


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    """xdist: every worker draws from the controller's seed."""
    node.workerinput["hypothesis_seed"] = getattr(node.config.option, "hypothesis_seed", None)


def _seed_line(config):
    seed = getattr(config.option, "hypothesis_seed", None)
    return None if seed is None else f"hypothesis seed: {seed} (rerun with {SEED_VARIABLE}={seed})"


def pytest_report_header(config):
    return _seed_line(config)


def pytest_terminal_summary(terminalreporter, config):
    line = _seed_line(config)
    if line is not None and not hasattr(config, "workerinput"):
        terminalreporter.write_line(line)


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


@pytest.fixture(scope="session")
def planning_lab():
    """The lab's cart-pole (``cartpole/assets/cartpole.xml``) for tests of a supervisor that plans (its own uses the
    energy law and never plans): ``(params, model, base, planner)``, ``base`` the :func:`supervisor_for` supervisor
    whose catch, basin level and brake a test's own :class:`Supervisor` takes, ``planner(x0, guess=None, cold=True)``
    the direct-collocation swing-up from ``x0``. Shared by tests/supervise/test_worker.py and
    tests/apps/test_swingup_live.py (built once a session)."""
    from cartpole.models import build_model, read_params
    from cartpole.planning.trajopt import trajopt_swingup
    from cartpole.supervise import supervisor_for

    params = read_params("cartpole/assets/cartpole.xml")
    model = build_model(params)
    base = supervisor_for(params, model)

    def planner(x0, guess=None, cold=True):
        return trajopt_swingup(params, x0=tuple(x0), plan_model=model, guess=guess, cold=cold)
    return params, model, base, planner
