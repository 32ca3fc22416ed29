"""The simulated building and robot: geometry with heights, ToF cones, drive physics."""

from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.obstacles import ObstacleSpec
from coffeebot.sim.world.robot import Pose, RobotSpec
from coffeebot.sim.world.tof import ConeOptics, RangingNoise, RangingSetup, SensorMount, ToFReading
from coffeebot.sim.world.world import Collision, UwbModel, World

__all__ = [
    "Collision",
    "ConeOptics",
    "ObstacleSpec",
    "Pose",
    "RangingNoise",
    "RangingSetup",
    "RobotSpec",
    "SensorMount",
    "Surfaces",
    "ToFReading",
    "UwbModel",
    "World",
]
