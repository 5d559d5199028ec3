"""URDF cart-poles written the way four kinds of authors write them (our own files, in their layouts), for the URDF
tests: Bullet's (slideBar base link, no transmission), Isaac Gym's (rail inside the cart, inertials without
<inertia>, no transmission), ROS's (world link, transmission_interface/SimpleTransmission, package:// meshes,
<gazebo> tags) and Drake's (default xmlns, <drake:...> tags, <transmission type="SimpleTransmission">, point
masses). Isaac Gym's pole also has a <collision> box, which the rail (welded to the world, so not its parent in
MuJoCo) could touch by the masks though never in space; it is left out here while the toolkit refuses contacts by
masks (cartpole.models.params), not by reachability. Each entry: the text, the joint its motor drives, the effort limit (None: unlimited), the source."""
from __future__ import annotations

from pathlib import Path

BULLET = """<?xml version="1.0"?>
<robot name="physics">
  <link name="slideBar">
    <visual>
      <geometry><box size="30 0.05 0.05"/></geometry>
      <origin xyz="0 0 0"/>
      <material name="green"><color rgba="0 0.8 .8 1"/></material>
    </visual>
    <inertial>
      <mass value="0"/>
      <inertia ixx="1.0" ixy="0.0" ixz="0.0" iyy="1.0" iyz="0.0" izz="1.0"/>
    </inertial>
  </link>
  <link name="cart">
    <visual><geometry><box size="0.5 0.5 0.2"/></geometry><origin xyz="0 0 0"/></visual>
    <collision><geometry><box size="0.5 0.5 0.2"/></geometry><origin xyz="0 0 0"/></collision>
    <inertial>
      <mass value="1"/>
      <inertia ixx="1.0" ixy="0.0" ixz="0.0" iyy="1.0" iyz="0.0" izz="1.0"/>
    </inertial>
  </link>
  <joint name="slider_to_cart" type="prismatic">
    <axis xyz="1 0 0"/>
    <origin xyz="0.0 0.0 0.0"/>
    <parent link="slideBar"/>
    <child link="cart"/>
    <limit effort="1000.0" lower="-15" upper="15" velocity="5"/>
  </joint>
  <link name="pole">
    <visual><geometry><box size="0.05 0.05 1.0"/></geometry><origin xyz="0 0 0.5"/></visual>
    <collision><geometry><box size="0.05 0.05 1.0"/></geometry><origin xyz="0 0 0.5"/></collision>
    <inertial>
      <origin xyz="0 0 0.5"/>
      <mass value="10"/>
      <inertia ixx="1" ixy="0.0" ixz="0.0" iyy="1" iyz="0.0" izz="1"/>
    </inertial>
  </link>
  <joint name="cart_to_pole" type="continuous">
    <axis xyz="0 1 0"/>
    <origin xyz="0.0 0.0 0"/>
    <parent link="cart"/>
    <child link="pole"/>
  </joint>
</robot>
"""

ISAAC = """<?xml version="1.0"?>
<robot name="cartpole">
  <link name="slider">
    <visual><geometry><box size="0.03 8 0.03"/></geometry></visual>
    <collision><geometry><box size="0.03 8 0.03"/></geometry></collision>
  </link>
  <link name="cart">
    <visual><geometry><box size="0.2 0.25 0.2"/></geometry></visual>
    <collision><geometry><box size="0.2 0.25 0.2"/></geometry></collision>
    <inertial><mass value="1"/></inertial>
  </link>
  <link name="pole">
    <visual><geometry><box size="0.04 0.04 1.0"/></geometry><origin xyz="0.0 0.0 0.48"/></visual>
    <inertial><mass value="1"/><origin xyz="0.0 0.0 0.48"/></inertial>
  </link>
  <joint name="slider_to_cart" type="prismatic">
    <axis xyz="0 1 0"/>
    <origin xyz="0 0 0"/>
    <parent link="slider"/>
    <child link="cart"/>
    <limit effort="180.0" lower="-4" upper="4" velocity="1.75"/>
  </joint>
  <joint name="cart_to_pole" type="continuous">
    <axis xyz="1 0 0"/>
    <origin xyz="0.15 0 0"/>
    <parent link="cart"/>
    <child link="pole"/>
    <limit effort="1.0" velocity="9.8"/>
  </joint>
</robot>
"""

ROS = """<?xml version="1.0"?>
<robot name="cart_pole" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <link name="world"/>
  <joint name="world_to_rail" type="fixed">
    <parent link="world"/>
    <child link="rail"/>
    <origin xyz="0 0 1.0" rpy="0 0 0"/>
  </joint>
  <link name="rail">
    <visual>
      <geometry><mesh filename="package://cart_pole_description/meshes/rail.dae"/></geometry>
    </visual>
    <inertial>
      <mass value="5"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/>
    </inertial>
  </link>
  <link name="cart">
    <visual>
      <geometry><mesh filename="package://cart_pole_description/meshes/cart.stl"/></geometry>
    </visual>
    <collision>
      <origin xyz="0 0 -0.1"/>
      <geometry><mesh filename="package://cart_pole_description/meshes/cart.obj"/></geometry>
    </collision>
    <inertial>
      <mass value="1.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial>
  </link>
  <link name="pole">
    <visual>
      <origin xyz="0 0 0.3"/>
      <geometry><cylinder radius="0.02" length="0.6"/></geometry>
    </visual>
    <collision>
      <origin xyz="0 0 0.3"/>
      <geometry><cylinder radius="0.02" length="0.6"/></geometry>
    </collision>
    <inertial>
      <origin xyz="0 0 0.3"/>
      <mass value="0.3"/>
      <inertia ixx="0.009" ixy="0" ixz="0" iyy="0.009" iyz="0" izz="0.0001"/>
    </inertial>
  </link>
  <joint name="cart_slider" type="prismatic">
    <parent link="rail"/>
    <child link="cart"/>
    <axis xyz="1 0 0"/>
    <limit lower="-1.5" upper="1.5" effort="50" velocity="3"/>
    <dynamics damping="0.5"/>
  </joint>
  <joint name="pole_hinge" type="continuous">
    <parent link="cart"/>
    <child link="pole"/>
    <origin xyz="0 0.08 0"/>
    <axis xyz="0 1 0"/>
    <dynamics damping="0.01"/>
  </joint>
  <transmission name="cart_trans">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="cart_slider">
      <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
    </joint>
    <actuator name="cart_motor">
      <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
      <mechanicalReduction>1</mechanicalReduction>
    </actuator>
  </transmission>
  <gazebo>
    <plugin name="gazebo_ros_control" filename="libgazebo_ros_control.so">
      <robotNamespace>/cart_pole</robotNamespace>
    </plugin>
  </gazebo>
  <gazebo reference="pole"><material>Gazebo/Orange</material></gazebo>
</robot>
"""

DRAKE = """<?xml version="1.0"?>
<robot xmlns="http://drake.mit.edu" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
       xmlns:drake="http://drake.mit.edu" name="CartPole">
  <link name="world"/>
  <link name="cart">
    <inertial>
      <mass value="10"/>
      <inertia ixx="1e-20" ixy="0" ixz="0" iyy="1e-20" iyz="0" izz="1e-20"/>
    </inertial>
    <visual><geometry><box size="0.24 0.12 0.12"/></geometry><material><color rgba="0 1 0 1"/></material></visual>
  </link>
  <link name="pole">
    <inertial>
      <origin xyz="0 0 -0.5"/>
      <mass value="1"/>
      <inertia ixx="1e-20" ixy="0" ixz="0" iyy="1e-20" iyz="0" izz="1e-20"/>
    </inertial>
    <visual><origin xyz="0 0 -0.25"/><geometry><cylinder radius="0.025" length="0.5"/></geometry></visual>
    <collision name="pole_point_mass">
      <origin xyz="0 0 -0.5"/>
      <geometry><sphere radius="0.05"/></geometry>
      <drake:proximity_properties><drake:mu_static value="0.8"/></drake:proximity_properties>
    </collision>
  </link>
  <joint name="CartSlider" type="prismatic">
    <parent link="world"/>
    <child link="cart"/>
    <axis xyz="1 0 0"/>
    <limit lower="-10" upper="10" effort="30"/>
    <drake:rotor_inertia value="0"/>
  </joint>
  <joint name="PolePin" type="continuous">
    <parent link="cart"/>
    <child link="pole"/>
    <axis xyz="0 -1 0"/>
    <dynamics damping="0.1"/>
  </joint>
  <transmission type="SimpleTransmission" name="cart_force">
    <actuator name="force"/>
    <joint name="CartSlider"/>
    <mechanicalReduction>1</mechanicalReduction>
  </transmission>
  <drake:collision_filter_group name="robot">
    <drake:member link="cart"/>
    <drake:member link="pole"/>
    <drake:ignored_collision_filter_group name="robot"/>
  </drake:collision_filter_group>
</robot>
"""

#: A cube of 0.3 m x 0.2 m x 0.1 m centred on its origin, the ROS layout's collision mesh.
CART_OBJ = "\n".join(
    [f"v {x} {y} {z}" for x in (-0.15, 0.15) for y in (-0.1, 0.1) for z in (-0.05, 0.05)]
    + ["f 1 3 4 2", "f 5 6 8 7", "f 1 2 6 5", "f 3 7 8 4", "f 1 5 7 3", "f 2 4 8 6"]) + "\n"

#: name -> (text, driven joint, effort limit, source)
LAYOUTS = {
    "bullet": (BULLET, "slider_to_cart", 1000.0, "single_prismatic"),
    "isaac": (ISAAC, "slider_to_cart", 180.0, "single_prismatic"),
    "ros": (ROS, "cart_slider", 50.0, "transmission"),
    "drake": (DRAKE, "CartSlider", 30.0, "transmission"),
}


def write_layout(name: str, folder: Path) -> Path:
    """Write layout ``name`` under ``folder`` (the ROS one inside a package with its collision mesh); its path."""
    text = LAYOUTS[name][0]
    if name == "ros":
        pkg = folder / "cart_pole_description"
        (pkg / "meshes").mkdir(parents=True, exist_ok=True)
        (pkg / "urdf").mkdir(exist_ok=True)
        (pkg / "meshes" / "cart.obj").write_text(CART_OBJ)
        path = pkg / "urdf" / "cart_pole.urdf"
    else:
        path = folder / f"{name}_cartpole.urdf"
    path.write_text(text)
    return path
