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
LOCALIZED_KEY = "/map/localized"  # bool: False while the grid SLAM has lost the robot and searches the map
RELOCALIZE_KEY = "/map/relocalize"  # bool: a leaf asks grid_slam to forget the pose and search the whole map
NAVIGATOR_KEY = "/nav/navigator"  # homing.navigation.Navigator
EXPLORE_GOAL_KEY = "/explore/goal"  # Pose2 in map or None, written by the Explore leaf
EXPLORED_KEY = "/explore/explored"  # bool: the last Explore ended "explored" (True) or has gone for a frontier since
LANDMARKS_KEY = "/slam/landmarks"  # dict[int, Pose2]: tag id → optimised tag pose in map, written by tag_slam
TAGS_KEY = "/perception/tags"  # this tick's tag measurements in base_link
FOCUS_KEY = "/perception/focus_until"  # [s] adapter time until which a leaf wants every camera frame looked at
STAGED_KEY = "/nav/staged"  # Pose2 in odom where the tag servo last reached the staging pose (None: not since it started)
DOCK_KEY = "/nav/dock"  # Pose2: the docked robot's pose in map (refreshed whenever the base charges on the dock)
ENERGY_KEY = "/energy/policy"  # {battery: {percent, undock, home, reserve}} [%], written by the energy service
HOME_DISTANCE_KEY = "/energy/distance_home"  # [m] planned travel distance to the staging pose
CYCLES_KEY = "/mission/cycles"  # int: dock cycles completed
IDLE_KEY = "/runner/idle_until"  # [s] adapter time until which the tree has nothing to do (set per tick)
SAVE_KEY = "/runner/save"  # bool: a leaf asks the runner to save a snapshot to the run directory after this tick
GOAL_UPDATE_KEY = "/nav/goal_update"  # a new goal pose (map) for GoalUpdater, written by a leaf or a Script
GOALS_UPDATE_KEY = "/nav/goals_update"  # a new list of goal poses for GoalUpdater
