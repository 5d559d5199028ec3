"""MJCF files of the cart-pole family that the tests write themselves (issue 10): carts with 1, 2 and 3 poles
written the way the best-known RL suite extends its single-pole file, Gymnasium's double and single
inverted pendulums as published, a two-pole chain with everything turned on (flipped axes, offsets,
armature and damping on every joint, a joint reference, a rotated full inertia, an asymmetric ctrlrange)
for every integrator, a pendulum, an acrobot (motor on the second hinge) and a cart with two motors."""
from __future__ import annotations

from pathlib import Path

_DMC_POLE = """<body name="pole_{i}" childclass="pole"{pos}>
          <joint name="hinge_{i}"/>
          <geom name="pole_{i}"/>
          {child}
        </body>"""


def dmc_cartpole(n_poles: int) -> str:
    """The RL suite's cart-pole with ``n_poles`` poles, built as its own ``_make_model`` builds it."""
    child = ""
    for i in range(n_poles, 0, -1):
        child = _DMC_POLE.format(i=i, pos="" if i == 1 else ' pos="0 0 1"', child=child)
    return f"""<mujoco model="cart-pole">
  <option timestep="0.01" integrator="RK4">
    <flag contact="disable" energy="enable"/>
  </option>
  <default>
    <default class="pole">
      <joint type="hinge" axis="0 1 0"  damping="2e-6"/>
      <geom type="capsule" fromto="0 0 0 0 0 1" size="0.045" mass=".1"/>
    </default>
  </default>
  <worldbody>
    <light name="light" pos="0 0 6"/>
    <camera name="fixed" pos="0 {-1 - 2 * n_poles} 1" zaxis="0 -1 0"/>
    <camera name="lookatcart" mode="targetbody" target="cart" pos="0 {-2 * n_poles} 2"/>
    <geom name="floor" pos="0 0 {1 - n_poles - 0.05}" size="4 4 .2" type="plane"/>
    <geom name="rail1" type="capsule" pos="0  .07 1" zaxis="1 0 0" size="0.02 2"/>
    <geom name="rail2" type="capsule" pos="0 -.07 1" zaxis="1 0 0" size="0.02 2"/>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" limited="true" axis="1 0 0" range="-1.8 1.8" solreflimit=".08 1" damping="5e-4"/>
      <geom name="cart" type="box" size="0.2 0.15 0.1" mass="1"/>
      {child}
    </body>
  </worldbody>
  <actuator>
    <motor name="slide" joint="slider" gear="10" ctrllimited="true" ctrlrange="-1 1" />
  </actuator>
</mujoco>
"""


GYM_DOUBLE = """<mujoco model="cartpole">
  <compiler angle="degree" inertiafromgeom="true"/>
  <default>
    <joint damping="0.05"/>
    <geom contype="0" friction="1 0.1 0.1" rgba="0.7 0.7 0 1"/>
  </default>
  <option gravity="1e-5 0 -9.81" integrator="RK4" timestep="0.01"/>
  <size nstack="3000"/>
  <worldbody>
    <geom name="floor" pos="0 0 -3.0" rgba="0.8 0.9 0.8 1" size="40 40 40" type="plane"/>
    <geom name="rail" pos="0 0 0" quat="0.707 0 0.707 0" rgba="0.3 0.3 0.7 1" size="0.02 1" type="capsule"/>
    <body name="cart" pos="0 0 0">
      <joint axis="1 0 0" limited="true" margin="0.01" name="slider" pos="0 0 0" range="-1 1" type="slide"/>
      <geom name="cart" pos="0 0 0" quat="0.707 0 0.707 0" size="0.1 0.1" type="capsule"/>
      <body name="pole" pos="0 0 0">
        <joint axis="0 1 0" name="hinge" pos="0 0 0" type="hinge"/>
        <geom fromto="0 0 0 0 0 0.6" name="cpole" rgba="0 0.7 0.7 1" size="0.045 0.3" type="capsule"/>
        <body name="pole2" pos="0 0 0.6">
          <joint axis="0 1 0" name="hinge2" pos="0 0 0" type="hinge"/>
          <geom fromto="0 0 0 0 0 0.6" name="cpole2" rgba="0 0.7 0.7 1" size="0.045 0.3" type="capsule"/>
          <site name="tip" pos="0 0 .6" size="0.01 0.01"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor ctrllimited="true" ctrlrange="-1 1" gear="500" joint="slider" name="slide"/>
  </actuator>
</mujoco>
"""

GYM_SINGLE = """<mujoco model="inverted pendulum">
  <compiler inertiafromgeom="true"/>
  <default>
    <joint armature="0" damping="1" limited="true"/>
    <geom contype="0" friction="1 0.1 0.1" rgba="0.7 0.7 0 1"/>
    <tendon/>
    <motor ctrlrange="-3 3"/>
  </default>
  <option gravity="0 0 -9.81" integrator="RK4" timestep="0.02"/>
  <size nstack="3000"/>
  <worldbody>
    <geom name="rail" pos="0 0 0" quat="0.707 0 0.707 0" rgba="0.3 0.3 0.7 1" size="0.02 1" type="capsule"/>
    <body name="cart" pos="0 0 0">
      <joint axis="1 0 0" limited="true" name="slider" pos="0 0 0" range="-1 1" type="slide"/>
      <geom name="cart" pos="0 0 0" quat="0.707 0 0.707 0" size="0.1 0.1" type="capsule"/>
      <body name="pole" pos="0 0 0">
        <joint axis="0 1 0" name="hinge" pos="0 0 0" range="-90 90" type="hinge"/>
        <geom fromto="0 0 0 0.001 0 0.6" name="cpole" rgba="0 0.7 0.7 1" size="0.049 0.3" type="capsule"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor gear="100" joint="slider" name="slide"/>
  </actuator>
</mujoco>
"""


def everything_chain(integrator: str) -> str:
    """Two poles with every feature the reader models, for ``integrator``."""
    return f"""<mujoco model="everything_{integrator}">
  <option timestep="0.004" integrator="{integrator}"><flag contact="disable"/></option>
  <worldbody>
    <body name="cart" pos="0.1 0 1.5" quat="0.9914449 0 0 0.1305262">
      <joint name="rail" type="slide" axis="-1 0 0" pos="0.02 0 0" range="-1.2 1.3" damping="0.3" armature="0.04"/>
      <geom type="box" size="0.1 0.05 0.05" mass="0.8"/>
      <body name="link1" pos="0.02 0.01 0.04">
        <joint name="shoulder" type="hinge" axis="0 -1 0" pos="0 0 -0.01" damping="0.02" armature="0.003"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0.15"/>
        <geom type="sphere" pos="0.03 0 0.5" size="0.04" mass="0.05"/>
        <body name="link2" pos="0 0 0.5" euler="0 20 0">
          <joint name="elbow" type="hinge" axis="0 1 0" ref="0.349065850" damping="0.01" armature="0.001"/>
          <inertial pos="0.01 0.005 0.2" quat="0.9238795 0.2209424 0.2209424 0.2209424" mass="0.12"
                    diaginertia="0.004 0.003 0.002"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.4" size="0.015" mass="0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="push" joint="rail" gear="25" ctrlrange="-0.8 1.2"/>
  </actuator>
</mujoco>
"""


PENDULUM = """<mujoco model="pendulum">
  <option timestep="0.002" integrator="RK4"><flag contact="disable"/></option>
  <worldbody>
    <body name="base" pos="0 0 1">
      <body name="pole" pos="0 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0.3"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="torque" joint="hinge" gear="2" ctrlrange="-1 1"/></actuator>
</mujoco>
"""

ACROBOT = """<mujoco model="acrobot">
  <option timestep="0.01" integrator="RK4"><flag contact="disable"/></option>
  <worldbody>
    <body name="upper_arm" pos="0 0 2">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0 0 1" size="0.045" mass="1"/>
      <body name="lower_arm" pos="0 0 1">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0 0 1" size="0.045" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="elbow" joint="elbow" gear="2" ctrlrange="-1 1"/></actuator>
</mujoco>
"""

TWO_MOTORS = """<mujoco model="cart_two_motors">
  <option timestep="0.005" integrator="implicitfast"><flag contact="disable"/></option>
  <worldbody>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0" range="-1.5 1.5" damping="0.1"/>
      <geom type="box" size="0.1 0.05 0.05" mass="1"/>
      <body name="pole" pos="0 0 0.05">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" mass="0.1"/>
        <body name="pole2" pos="0 0 0.6">
          <joint name="hinge2" type="hinge" axis="0 1 0" damping="0.01"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" mass="0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="cart" joint="slider" gear="20" ctrlrange="-1 1"/>
    <motor name="wrist" joint="hinge2" gear="1" ctrlrange="-0.5 0.5"/>
  </actuator>
</mujoco>
"""

#: name -> MJCF text of every family member the model tests cover.
CHAINS = {
    "dmc_1pole": dmc_cartpole(1),
    "dmc_2poles": dmc_cartpole(2),
    "dmc_3poles": dmc_cartpole(3),
    "gym_double": GYM_DOUBLE,
    "gym_single_off_vertical": GYM_SINGLE,
    **{f"everything_{i}": everything_chain(i) for i in ("Euler", "RK4", "implicit", "implicitfast")},
    "pendulum": PENDULUM,
    "acrobot": ACROBOT,
    "two_motors": TWO_MOTORS,
}


def write_chain(directory: Path, name: str) -> Path:
    """Write chain ``name`` into ``directory`` and return its path."""
    path = Path(directory) / f"{name}.xml"
    path.write_text(CHAINS[name])
    return path
