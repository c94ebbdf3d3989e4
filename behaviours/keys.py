"""The blackboard keys the parts share (ARCHITECTURE.md, "Blackboard keys").

One place for the names, so that a service writing ``/map/grid`` and the
leaves reading it cannot drift apart. Keys that belong to one module only
(a leaf's own goal slot, say) stay in that module.
"""

OBSERVATION_KEY = "/robot/observation"  # homing.robot.Observation, written by the runner each tick
TIME_KEY = "/robot/time"  # [s] adapter clock, written by the runner
CMD_VEL_KEY = "/cmd_vel"  # homing.robot.Twist2, written by the leaf driving this tick
STATE_KEY = "/mission/state"  # lifecycle state shown in the live view
GRID_KEY = "/map/grid"  # homing.mapping.grid.OccupancyGrid
POSE_KEY = "/map/pose"  # Pose2, base_link in map
MAP_TO_ODOM_KEY = "/map/map_to_odom"  # Pose2
NAVIGATOR_KEY = "/nav/navigator"  # homing.navigation.Navigator
EXPLORE_GOAL_KEY = "/explore/goal"  # Pose2 in map or None, written by the Explore leaf
TAGS_KEY = "/perception/tags"  # this tick's tag measurements in base_link
