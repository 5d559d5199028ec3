"""Cart-pole MJCF variants that the tests write themselves (issue 2): every integrator, other time steps,
gears, damping, armature, hinge offsets, a flipped hinge axis and a heavier pole. All keep the rail raised
so the pole swings freely."""
from __future__ import annotations

from pathlib import Path

TEMPLATE = """<mujoco model="cartpole_{name}">
  <option timestep="{timestep}" gravity="0 0 -9.81" integrator="{integrator}"><flag contact="disable"/></option>
  <visual><global offwidth="320" offheight="240"/></visual>
  <worldbody>
    <light pos="0 -1 3" dir="0 0.3 -1"/>
    <camera name="track" pos="0 -4.2 1.05" xyaxes="1 0 0 0 0 1"/>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="cart" pos="0 0 1.2">
      <joint name="slider" type="slide" axis="1 0 0" limited="true" range="-{track} {track}"
             damping="{cart_damping}" armature="{cart_armature}"/>
      <geom name="cart_geom" type="box" size="0.1 0.05 0.05" mass="{cart_mass}"/>
      <body name="pole" pos="{hinge_offset}">
        <joint name="hinge" type="hinge" axis="{hinge_axis}" damping="{pole_damping}" armature="{pole_armature}"/>
        <geom name="pole_geom" type="capsule" fromto="0 0 0 0 0 {pole_length}" size="0.02" mass="{pole_mass}"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="motor" joint="slider" gear="{gear}" ctrlrange="-{ctrl_max} {ctrl_max}"/>
  </actuator>
</mujoco>
"""

BASE = dict(timestep=0.005, integrator="Euler", track=1.5, cart_damping=0.1, cart_armature=0.0,
            cart_mass=1.0, hinge_offset="0 0 0.05", hinge_axis="0 1 0", pole_damping=0.01,
            pole_armature=0.0, pole_length=0.6, pole_mass=0.1, gear=20, ctrl_max=1)

#: name -> overrides of BASE. Each changes several things at once so few variants cover every feature.
VARIANTS = {
    "rk4_fine_step": dict(integrator="RK4", timestep=0.002),
    "implicitfast_gear": dict(integrator="implicitfast", gear=30, ctrl_max=0.8, timestep=0.004),
    "implicit_damped": dict(integrator="implicit", cart_damping=0.5, pole_damping=0.03),
    "flipped_offset_armature": dict(hinge_axis="0 -1 0", hinge_offset="0.03 0 0.08", pole_armature=0.002,
                                    cart_armature=0.05),
    "heavy_pole": dict(pole_mass=0.3, pole_length=0.8, cart_mass=1.5, gear=30, timestep=0.004),
}


def variant_xml(name: str) -> str:
    """The MJCF text of variant ``name``."""
    return TEMPLATE.format(name=name, **{**BASE, **VARIANTS[name]})


def write_variant(directory: Path, name: str) -> Path:
    """Write variant ``name`` into ``directory`` and return its path."""
    path = Path(directory) / f"cartpole_{name}.xml"
    path.write_text(variant_xml(name))
    return path
