"""The command line on files with contacts on: `model.contacts` in the JSON, one sentence and exit 2 where a pair
touches where the command needs to go (issue 38, class 1)."""
import json

from cartpole.cli import main

TEMPLATE = """<mujoco model="published">
  <option timestep="0.005"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    {extra}
    <body name="cart" pos="0 0 {cart_z}">
      <joint name="slider" type="slide" axis="1 0 0" limited="true" range="-1.5 1.5"/>
      <geom name="cart_geom" type="box" size="0.1 0.05 0.05" mass="1"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom name="pole_geom" type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/></actuator>
</mujoco>"""


def write(tmp_path, name, *, cart_z, extra=""):
    path = tmp_path / f"{name}.xml"
    path.write_text(TEMPLATE.format(cart_z=cart_z, extra=extra))
    return path


def test_linearize_lists_pairs_that_never_touch_in_model_contacts(tmp_path, capsys):
    path = write(tmp_path, "high", cart_z=0.8)
    assert main(["linearize", "--json", "--mjcf", str(path)]) == 0
    contacts = json.loads(capsys.readouterr().out)["model"]["contacts"]
    assert contacts["enabled"] and len(contacts["pairs"]) == 2
    assert {p["classification"] for p in contacts["pairs"]} == {"never"}
    assert all(p["min_clearance"] > 0 for p in contacts["pairs"])


def test_a_pair_touching_at_upright_ends_in_one_sentence_and_exit_2(tmp_path, capsys):
    rail = '<geom name="rail" type="box" size="2 0.02 0.02" pos="0 0 0.8"/>'
    path = write(tmp_path, "rail", cart_z=0.8, extra=rail)
    for command in (["linearize"], ["lqr", "--no-video", "--out", str(tmp_path / "out")]):
        assert main([*command, "--json", "--mjcf", str(path)]) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.count("\n") == 1 and err.rstrip().endswith(".")
        assert "'rail' and 'cart_geom' touch at the upright equilibrium (0.07 m deep)" in err and "floor" not in err
    assert not (tmp_path / "out").exists()


def test_a_short_rail_balances_with_lqr_and_its_swing_up_is_refused_naming_where(tmp_path, capsys):
    path = write(tmp_path, "short", cart_z=0.3)
    out = tmp_path / "out"
    assert main(["lqr", "--json", "--no-video", "--mjcf", str(path), "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    pairs = {(p["geom1"], p["geom2"]): p for p in doc["model"]["contacts"]["pairs"]}
    assert pairs[("floor", "pole_geom")]["classification"] == "away_from_upright"
    assert pairs[("floor", "cart_geom")]["classification"] == "never"
    assert all("contact" not in r for r in doc["rollouts"])  # the lab's starts near upright never reach the floor
    swing_out = tmp_path / "swing"
    assert main(["swingup", "--json", "--no-video", "--mjcf", str(path), "--out", str(swing_out)]) == 2
    stdout, err = capsys.readouterr()
    assert stdout == "" and err.count("\n") == 1
    assert "'floor' and 'pole_geom' touch on the way up (hinge 'hinge' within" in err and "rad of hanging" in err
    assert not swing_out.exists()


def test_swingup_json_carries_model_contacts(tmp_path, capsys):
    path = write(tmp_path, "high", cart_z=0.8)
    assert main(["swingup", "--json", "--no-video", "--mjcf", str(path), "--out", str(tmp_path), "--duration",
                 "0.5"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {p["classification"] for p in doc["model"]["contacts"]["pairs"]} == {"never"}
    assert doc["metrics"]["contact"] is None and "contact" not in doc["rollout"]
