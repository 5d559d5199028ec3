"""The fresh-process swing-up benchmark of the shipped chains: one process on the single pole, its keys and the plan
it verified; no timing is asserted."""
import io

import pytest

from cartpole.apps.bench.swingup_chains import print_chains_table, shipped_chain_carts, swingup_chains_benchmark
from cartpole.models import SHIPPED_MJCF


def test_the_shipped_chains_are_found_by_their_pole_count():
    carts = shipped_chain_carts()
    assert sorted(carts) == [1, 2, 3] and carts[1] == str(SHIPPED_MJCF)


def test_one_fresh_process_plans_and_verifies_the_single_pole():
    doc = swingup_chains_benchmark([1], repeats=1)
    assert doc["repeats"] == 1 and doc["baseline"] is None and list(doc["carts"]) == [1]
    r = doc["carts"][1]
    for key in ("mjcf", "wall_s", "import_s", "plan_s", "rollout_s", "wall_s_runs", "plan_s_runs", "T_min", "T",
                "time_to_upright", "success", "objective", "solves", "iterations", "all_succeeded"):
        assert key in r, key
    assert len(r["wall_s_runs"]) == len(r["plan_s_runs"]) == 1
    assert r["wall_s"] > r["import_s"] + r["plan_s"]  # the process's wall time holds its parts
    assert r["success"] and r["all_succeeded"] and r["T"] >= r["T_min"] > 0
    out = io.StringIO()
    print_chains_table(doc, file=out)
    assert out.getvalue().splitlines()[1].split()[0] == "1" and out.getvalue().rstrip().endswith("True")


def test_a_cart_that_is_not_shipped_is_one_sentence():
    with pytest.raises(ValueError, match="No shipped cart has 4 poles"):
        swingup_chains_benchmark([4], repeats=1)
