"""Which homing node each BehaviorTree.CPP and Nav2 node becomes, port by port, and which have none (and why).

One :class:`Rule` per XML node name: the homing node, how each attribute
(port) turns into a homing parameter — with the unit conversions the field's
names blur (BT.CPP counts milliseconds, homing seconds; Nav2's battery
fraction is homing's percent) — which attributes have no meaning in homing
and why (ROS action server names, plugin IDs: homing's navigation service
has one planner and one controller, chosen in ``services:``), and the
semantic difference, if any, that an importer reports. :data:`NO_EQUIVALENT`
names the nodes homing cannot run, each with the reason, so an import fails
on them with a message rather than dropping them; :data:`PY_TREES` does the
same for py_trees' composites and decorators, for the README's table.

Conversions (the second item of a port): ``float``, ``int``, ``bool``,
``text``, ``list`` (BT.CPP's ``a;b;c``), ``codes`` (Nav2's numeric error codes → homing's
typed reasons, :data:`NAV2_ERROR_CODES`), ``key`` (a blackboard port
``{goal}`` becomes the key parameter ``goal``), ``ms`` (milliseconds →
seconds), ``abs`` (a distance whatever its sign), ``fraction`` (0..1 → %).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from homing.behaviours.goal_checks import CONTROLLER_REASONS, PLANNER_REASONS
from homing.behaviours.smoothing import SMOOTHER_REASONS


@dataclass(frozen=True)
class Rule:
    """How one BT.CPP or Nav2 node becomes a homing node (see the module doc for conversions)."""

    homing: str
    ports: dict[str, tuple[str, str]] = field(default_factory=dict)
    ignore: dict[str, str] = field(default_factory=dict)
    fixed: dict[str, Any] = field(default_factory=dict)
    note: str = ""
    source: str = "BT.CPP"
    kind: str = "leaf"  # leaf, decorator, control: how its XML children map (none, one, several)


NAV2_SERVER = {
    "server_name": "homing calls its navigation service directly (no ROS action server)",
    "server_timeout": "no action server to wait for",
    "error_msg": "homing's leaves write a typed reason (failure_key), no message",
    "is_recovery": "no recovery counter in homing",
    "disable_collision_checks": "homing's motions always check the scan",
}
FRAMES = {
    "global_frame": "homing's poses are in map (REP-105)",
    "robot_base_frame": "homing's robot frame is base_link",
    "transform_tolerance": "no TF in homing",
}
PLUGIN_IDS = {
    "planner_id": "homing's navigation service has one planner, chosen in services:",
    "controller_id": "homing's navigation service has one controller, chosen in services:",
    "goal_checker_id": "one goal checker (the tolerances of FollowPath)",
    "progress_checker_id": "one progress checker (the navigator's)",
}

CLEARING = {
    "service_name": "homing has one costmap: its obstacle layer is cleared",
    "plugins": "homing clears the layers its sensors fill (obstacles, bumper marks); static and keep-out stay",
}

# Nav2's numeric error codes (nav2_msgs FollowPath 1xx, ComputePathToPose 2xx, ComputePathThroughPoses 3xx,
# SmoothPath 5xx) as the typed reasons homing's leaves write to their failure_key, for AreErrorCodesPresent.
NAV2_ERROR_CODES: dict[int, str] = {
    100: "failed", 103: "invalid_path", 104: "timed_out", 105: "no_progress", 106: "blocked", 107: "timed_out",
    **{base + off: reason for base in (200, 300) for off, reason in (
        (0, "failed"), (5, "start_occupied"), (6, "goal_occupied"), (7, "timed_out"), (8, "no_path"))},
    309: "no_goal",
    500: "failed", 502: "timed_out", 503: "smoothed_path_in_collision", 505: "invalid_path",
}
NAV2_ERRORS_NEVER_REPORTED: dict[int, str] = {
    101: "INVALID_CONTROLLER: one controller", 102: "TF_ERROR: no TF",
    501: "INVALID_SMOOTHER: one smoother", 504: "FAILED_TO_SMOOTH_PATH: its smoothing never throws",
    **{base + off: f"{name}: {why}" for base in (200, 300) for off, name, why in (
        (1, "INVALID_PLANNER", "one planner"), (2, "TF_ERROR", "no TF"),
        (3, "START_OUTSIDE_MAP", "the costmap grows to span the start"),
        (4, "GOAL_OUTSIDE_MAP", "the costmap grows to span the goal"))},
}


def _nav2(homing: str, ports: dict[str, tuple[str, str]], ignore: dict[str, str] | None = None,
          note: str = "", **fixed: Any) -> Rule:  # fmt: skip
    return Rule(homing, ports, {**NAV2_SERVER, **FRAMES, **PLUGIN_IDS, **(ignore or {})}, fixed, note, "Nav2")


RULES: dict[str, Rule] = {
    # ---- BT.CPP control nodes
    "Sequence": Rule("sequence", kind="control"),
    "SequenceWithMemory": Rule("sequence_with_memory", kind="control"),
    "SequenceStar": Rule("sequence_with_memory", kind="control", source="BT.CPP v3"),
    "ReactiveSequence": Rule("reactive_sequence", kind="control"),
    "AsyncSequence": Rule("sequence", kind="control",
                          note="AsyncSequence returns RUNNING between children; homing's sequence goes on in the same tick"),
    "Fallback": Rule("fallback", kind="control"),
    "AsyncFallback": Rule("fallback", kind="control",
                          note="AsyncFallback returns RUNNING between children; homing's fallback goes on in the same tick"),
    "ReactiveFallback": Rule("reactive_fallback", kind="control"),
    "IfThenElse": Rule("if_then_else", kind="control"),
    "WhileDoElse": Rule("while_do_else", kind="control"),
    "Parallel": Rule("parallel", kind="control"),
    "ParallelNode": Rule("parallel", kind="control"),
    **{f"Switch{n}": Rule("switch", kind="control") for n in range(2, 7)},
    # ---- BT.CPP decorators
    "Inverter": Rule("inverter", kind="decorator"),
    "ForceSuccess": Rule("force_success", kind="decorator"),
    "ForceFailure": Rule("force_failure", kind="decorator"),
    "Repeat": Rule("repeat", {"num_cycles": ("times", "int")}, kind="decorator",
                   note="BT.CPP repeats within one tick; homing starts each cycle on the next tick"),
    "RetryUntilSuccessful": Rule("retry", {"num_attempts": ("attempts", "int")}, kind="decorator",
                                 note="BT.CPP retries within one tick; homing starts each attempt on the next tick"),
    "RetryUntilSuccesful": Rule("retry", {"num_attempts": ("attempts", "int")}, kind="decorator", source="BT.CPP v3",
                                note="BT.CPP retries within one tick; homing starts each attempt on the next tick"),
    "KeepRunningUntilFailure": Rule("keep_running_until_failure", kind="decorator"),
    "Timeout": Rule("timeout", {"msec": ("seconds", "ms")}, kind="decorator"),
    "Delay": Rule("delay", {"delay_msec": ("seconds", "ms")}, kind="decorator"),
    "RunOnce": Rule("run_once", {"then_skip": ("then_skip", "bool")}, kind="decorator"),
    # ---- BT.CPP leaves
    "AlwaysSuccess": Rule("Succeed"),
    "AlwaysFailure": Rule("Fail"),
    "SetBlackboard": Rule("SetBlackboard", {"output_key": ("key", "key"), "value": ("value", "text")}),
    "Sleep": Rule("Wait", {"msec": ("seconds", "ms")}),
    "Script": Rule("Script", {"code": ("code", "text")}),
    "ScriptCondition": Rule("ScriptCondition", {"code": ("code", "text")}),
    # ---- Nav2 control nodes and decorators
    "RecoveryNode": Rule("recovery", {"number_of_retries": ("retries", "int")}, kind="control", source="Nav2"),
    "RoundRobin": Rule("round_robin", ignore={"wrap_around": "homing's round_robin wraps round (checked by the "
                                                            "importer: only true)"}, kind="control", source="Nav2"),
    "PipelineSequence": Rule("pipeline_sequence", kind="control", source="Nav2"),
    "RateController": Rule("rate_controller", {"hz": ("hz", "float")}, kind="decorator", source="Nav2"),
    "DistanceController": Rule("distance_controller", {"distance": ("distance", "float")}, FRAMES,
                               kind="decorator", source="Nav2"),
    "SpeedController": Rule("speed_controller", {
        "min_rate": ("min_rate", "float"), "max_rate": ("max_rate", "float"), "min_speed": ("min_speed", "float"),
        "max_speed": ("max_speed", "float"), "filter_duration": ("filter_duration", "float"),
        "goal": ("goal_key", "key")}, {"goals": "homing's speed_controller watches one goal key"},
        kind="decorator", source="Nav2"),
    "SingleTrigger": Rule("single_trigger", kind="decorator", source="Nav2"),
    "GoalUpdater": Rule("GoalUpdater", {"input_goal": ("input_goal", "key"), "input_goals": ("input_goals", "key"),
                                        "output_goal": ("output_goal", "key"), "output_goals": ("output_goals", "key")},
                        kind="decorator", source="Nav2",
                        note="the update comes from the blackboard entry /nav/goal_update (a leaf or a Script "
                             "writes it), not a ROS topic"),
    "GoalUpdatedController": Rule("GoalUpdatedController", {"goal": ("goal_key", "key"), "goals": ("goals_key", "key")},
                                  kind="decorator", source="Nav2"),
    "NonblockingSequence": Rule("nonblocking_sequence", kind="control", source="Nav2"),
    "PersistentSequence": Rule("persistent_sequence", {"current_child_idx": ("index_key", "key")}, kind="control",
                               source="Nav2"),
    "PathLongerOnApproach": Rule("path_longer_on_approach", {"path": ("path_key", "key"), "prox_len": ("prox_len", "float"),
                                 "length_factor": ("length_factor", "float")}, kind="decorator", source="Nav2"),
    "TruncatePath": _nav2("TruncatePath", {"distance": ("distance", "float"), "input_path": ("input_key", "key"),
                                           "output_path": ("output_key", "key")}),
    "GetPoseFromPath": _nav2("GetPoseFromPath", {"path": ("path_key", "key"), "index": ("index", "int"),
                                                 "pose": ("pose_key", "key")}),
    "ConcatenatePaths": _nav2("ConcatenatePaths", {"input_path1": ("input_key1", "key"),
                                                   "input_path2": ("input_key2", "key"),
                                                   "output_path": ("output_key", "key")}),
    "ArePosesNear": _nav2("ArePosesNear", {"ref_pose": ("ref_key", "key"), "target_pose": ("target_key", "key"),
                                           "tolerance": ("tolerance", "float")}),
    "DriveOnHeading": _nav2("DriveOnHeading", {"dist_to_travel": ("distance", "float"), "speed": ("speed", "float"),
                                               "time_allowance": ("timeout", "float"),
                                               "error_code_id": ("failure_key", "key")}, timeout=10.0),
    **{f"Cancel{what}": _nav2("Stop", {}, note=f"homing's {what} runs in its own leaf, which a halt stops; "
                                                f"Cancel{what} stops the base this tick") for what in (
        "Control", "BackUp", "Spin", "Wait", "DriveOnHeading")},
    "IsStopped": _nav2("IsStopped", {"velocity_threshold": ("velocity_threshold", "float"),
                                     "duration_stopped": ("duration", "ms")}),
    "IsStuck": _nav2("IsStuck", {}),
    "GetCurrentPose": _nav2("GetCurrentPose", {"current_pose": ("pose_key", "key")}),
    "PathExpiringTimer": _nav2("PathExpiringTimer", {"seconds": ("seconds", "float"), "path": ("path_key", "key")}),
    "PauseResumeController": Rule("pause_resume_controller", {"pause_service_name": ("pause_key", "key"),
                                                              "resume_service_name": ("resume_key", "key")},
                                  kind="control", source="Nav2",
                                  note="a call to the pause (resume) service is true written to the blackboard entry "
                                       "of that name"),
    # ---- BT.CPP 4 control nodes added after 4.0
    "TryCatch": Rule("try_catch", {"catch_on_halt": ("catch_on_halt", "bool")}, kind="control"),
    # ---- Nav2 actions and conditions
    "ComputePathToPose": _nav2("ComputePathToPose", {"goal": ("goal_key", "key"), "path": ("path_key", "key"),
                                                     "error_code_id": ("failure_key", "key")}),
    "ComputePathThroughPoses": _nav2("ComputePathThroughPoses", {"goals": ("goals_key", "key"), "path": ("path_key", "key"),
                                                                 "error_code_id": ("failure_key", "key")}),
    "FollowPath": _nav2("FollowPath", {"path": ("path_key", "key"), "error_code_id": ("failure_key", "key")},
                        {"tracking_feedback": "homing's FollowPath reports progress in its feedback message"}),
    "NavigateToPose": _nav2("NavigateToPose", {"goal": ("goal_key", "key"), "error_code_id": ("failure_key", "key")},
                            {"behavior_tree": "homing's NavigateToPose drives with its navigator, not a tree"}),
    "NavigateThroughPoses": _nav2("NavigateThroughPoses", {"goals": ("goals_key", "key"),
                                                           "error_code_id": ("failure_key", "key")},
                                  {"behavior_tree": "homing's NavigateThroughPoses drives with its navigator, not a tree"}),
    "SmoothPath": _nav2("SmoothPath", {
        "unsmoothed_path": ("input_key", "key"), "smoothed_path": ("output_key", "key"),
        "check_for_collisions": ("check_for_collisions", "bool"), "was_completed": ("completed_key", "key"),
        "error_code_id": ("failure_key", "key")},
        {"smoother_id": "homing has one smoother (Nav2's SimpleSmoother)",
         "max_smoothing_duration": "homing's smoothing is bounded by its sweeps (1000), not the wall clock, so runs "
                                   "repeat exactly",
         "smoothing_duration": "homing does not time its smoothing"}),
    "WouldASmootherRecoveryHelp": _nav2("FailureIs", {"error_code": ("key", "key")}, reasons=list(SMOOTHER_REASONS),
                                        note="Nav2's UNKNOWN, TIMEOUT, SMOOTHED_PATH_IN_COLLISION as homing's typed "
                                             "reasons (FAILED_TO_SMOOTH_PATH: homing's smoothing never throws)"),
    "ReinitializeGlobalLocalization": _nav2(
        "ReinitializeGlobalLocalization", {},
        {"service_name": "homing asks its grid_slam service through /map/relocalize (no AMCL service)"},
        note="grid_slam looks for the robot in the whole map, as AMCL spreads its particles over it"),
    "TransformAvailable": Rule("Succeed", {}, {"child": "one of homing's frames (checked by the importer)",
                                               "parent": "one of homing's frames (checked by the importer)"},
                               source="Nav2", kind="leaf",
                               note="homing's frames (map, odom, base_link, laser, camera) are there from the first "
                                    "tick: the transform is available"),
    "Spin": _nav2("Spin", {"spin_dist": ("angle", "float"), "time_allowance": ("timeout", "float"),
                           "error_code_id": ("failure_key", "key")}, timeout=10.0, angle=1.57),
    "BackUp": _nav2("BackUp", {"backup_dist": ("distance", "abs"), "backup_speed": ("speed", "abs"),
                               "time_allowance": ("timeout", "float"), "error_code_id": ("failure_key", "key")},
                    timeout=10.0, distance=0.15, speed=0.025),
    "Wait": _nav2("Wait", {"wait_duration": ("seconds", "float")},
                  {"error_code_id": "homing's Wait never fails, so it has no reason to write"}, seconds=1.0),
    "ClearEntireCostmap": _nav2("ClearCostmap", {}, {"service_name": "homing has one costmap: its obstacle layer is cleared"}),
    "ClearCostmapAroundRobot": _nav2("ClearCostmapAroundRobot", {"reset_distance": ("reset_distance", "float")},
                                     CLEARING),
    "ClearCostmapAroundPose": _nav2("ClearCostmapAroundPose", {"pose": ("pose_key", "key"),
                                                               "reset_distance": ("reset_distance", "float")},
                                    CLEARING),
    "ClearCostmapExceptRegion": _nav2("ClearCostmapExceptRegion", {"reset_distance": ("reset_distance", "float")},
                                      CLEARING),
    "TruncatePathLocal": _nav2("TruncatePathLocal", {
        "input_path": ("input_key", "key"), "output_path": ("output_key", "key"),
        "distance_forward": ("distance_forward", "float"), "distance_backward": ("distance_backward", "float"),
        "angular_distance_weight": ("angular_distance_weight", "float"),
        "max_robot_pose_search_dist": ("max_robot_pose_search_dist", "float"), "pose": ("pose_key", "key")},
        {"robot_frame": "the robot's pose is /map/pose (base_link in map) unless pose is given"}),
    "RemoveInCollisionGoals": _nav2("RemoveInCollisionGoals", {
        "input_goals": ("input_key", "key"), "output_goals": ("output_key", "key"),
        "cost_threshold": ("cost_threshold", "float"), "use_footprint": ("use_footprint", "bool"),
        "consider_unknown_as_obstacle": ("consider_unknown_as_obstacle", "bool")},
        {"service_name": "homing reads its one costmap directly (no get_costs service)",
         "input_waypoint_statuses": "homing keeps no waypoint statuses",
         "output_waypoint_statuses": "homing keeps no waypoint statuses"}),
    "RemovePassedGoals": _nav2("RemovePassedGoals", {"input_goals": ("input_key", "key"), "output_goals": ("output_key", "key"),
                                                     "radius": ("radius", "float")}),
    "IsPathValid": _nav2("IsPathValid", {"path": ("path_key", "key")},
                         {"max_cost": "homing checks against the robot's inscribed cost",
                          "consider_unknown_as_obstacle": "unknown cells count as the planner's allow_unknown says"}),
    "GoalUpdated": _nav2("GoalUpdated", {"goal": ("goal_key", "key"), "goals": ("goals_key", "key")}),
    "GlobalUpdatedGoal": _nav2("GlobalUpdatedGoal", {"goal": ("goal_key", "key"), "goals": ("goals_key", "key")}),
    "GoalReached": _nav2("GoalReached", {"goal": ("goal_key", "key")}),
    "TimeExpired": _nav2("TimeExpired", {"seconds": ("seconds", "float")}),
    "DistanceTraveled": _nav2("DistanceTraveled", {"distance": ("distance", "float")}),
    "IsBatteryLow": _nav2("BatteryBelow", {"min_battery": ("percent", "fraction")},
                          {"battery_topic": "the battery comes from the adapter", "is_voltage": "checked apart"}),
    "UndockRobot": _nav2("Undock", {"max_undocking_time": ("timeout", "float"), "error_code_id": ("failure_key", "key")},
                         {"dock_type": "homing's robot has one dock"}, turn=0.0, timeout=30.0,
                         note="homing's Undock backs straight out; Nav2's does not turn either (turn: 0)"),
    "DockRobot": _nav2("AutoDock", {"max_staging_time": ("timeout", "float"), "error_code_id": ("failure_key", "key")},
                       {"dock_id": "homing's robot has one dock (the navigation service's /nav/dock)",
                        "dock_type": "homing's robot has one dock", "use_dock_id": "homing's robot has one dock",
                        "navigate_to_staging_pose": "read by the importer: GoHome first unless false"},
                       note="GoHome to the staging pose, then AutoDock (IR): Nav2's DockRobot in homing's leaves"),
    "IsBatteryCharging": _nav2("BatteryCharging", {}, {"battery_topic": "the battery comes from the adapter"}),
    "AreErrorCodesPresent": _nav2("FailureIs", {"error_code": ("key", "key"), "error_codes_to_check": ("reasons", "codes")},
                                  note="Nav2's numeric planner and controller error codes as homing's typed reasons"),
    "WouldAPlannerRecoveryHelp": _nav2("FailureIs", {"error_code": ("key", "key")}, reasons=list(PLANNER_REASONS),
                                       note="Nav2's error codes UNKNOWN, NO_VALID_PATH, TIMEOUT as homing's typed reasons"),
    "WouldAControllerRecoveryHelp": _nav2(
        "FailureIs", {"error_code": ("key", "key")}, reasons=list(CONTROLLER_REASONS),
        note="Nav2's UNKNOWN, PATIENCE_EXCEEDED, FAILED_TO_MAKE_PROGRESS, NO_VALID_CONTROL as homing's typed reasons"),
}

# Nav2's selector nodes pick a plugin from a ROS topic, else the default: homing selects the default.
SELECTORS = {
    "ControllerSelector": ("selected_controller", "default_controller"),
    "PlannerSelector": ("selected_planner", "default_planner"),
    "GoalCheckerSelector": ("selected_goal_checker", "default_goal_checker"),
    "ProgressCheckerSelector": ("selected_progress_checker", "default_progress_checker"),
    "SmootherSelector": ("selected_smoother", "default_smoother"),
}
for _name, (_out, _default) in SELECTORS.items():
    RULES[_name] = Rule("SetBlackboard", {_out: ("key", "key"), _default: ("value", "text")},
                        {"topic_name": "no ROS topics: the default is selected"}, source="Nav2",
                        note="selects the default (no ROS topic to listen to)")

# Nodes with no homing equivalent, and why (an import fails on them, naming each).
NO_EQUIVALENT: dict[str, str] = {
    "ManualSelector": "it asks a person at a terminal which child to run",
    "ParallelAll": "it waits for every child even once the outcome is decided; use parallel with success: N",
    "Precondition": "use a ScriptCondition before the node in a sequence, or while_do_else",
    "LoopInt": "homing's blackboard holds no queues to loop over", "LoopDouble": "homing's blackboard holds no queues",
    "LoopString": "homing's blackboard holds no queues", "LoopBool": "homing's blackboard holds no queues",
    "ConsumeQueue": "homing's blackboard holds no queues",
    "SkipUnlessUpdated": "no per-entry update stamps on py_trees' blackboard",
    "WaitValueUpdate": "no per-entry update stamps on py_trees' blackboard",
    "EntryUpdated": "no per-entry update stamps on py_trees' blackboard",
    "UnsetBlackboard": "use Script to overwrite the entry",
    "BlackboardCheckInt": "use while_do_else with a ScriptCondition (value_A == value_B)",
    "BlackboardCheckDouble": "use while_do_else with a ScriptCondition (value_A == value_B)",
    "BlackboardCheckString": "use while_do_else with a ScriptCondition (value_A == value_B)",
    "Finally": "not in BT.CPP 4's factory (only on a development branch): use try_catch, or a sequence then cleanup",
    "LatchedSequence": "not in BT.CPP 4's factory (a v3-era branch only): use sequence_with_memory",
    "LatchedFallback": "not in BT.CPP 4's factory (a v3-era branch only): use fallback",
    "ParallelFirst": "not in BT.CPP 4's factory (a v3-era branch only): use parallel with success: 1",
    "ReactiveParallel": "not in BT.CPP 4's factory (a development branch only): use parallel",
    "AssistedTeleop": "it drives by an operator's twists on the ROS topic cmd_vel_teleop (Nav2's behavior "
                      "server), and homing has no operator input",
    "InitialPoseReceived": "it waits for a pose on ROS's /initialpose topic (RViz's 2D Pose Estimate); homing's "
                           "SLAM starts at its first pose and takes none",
    "CancelAssistedTeleop": "it cancels the AssistedTeleop ROS action of Nav2's behavior server, which homing has not",
    "CancelComputeAndTrackRoute": "it cancels the compute_and_track_route ROS action of Nav2's route server, which "
                                  "homing has not",
    "ComputeRoute": "it calls Nav2's route server (the compute_route ROS action, on a GeoJSON graph of waypoints), "
                    "which homing has not",
    "ComputeAndTrackRoute": "it calls Nav2's route server (the compute_and_track_route ROS action), which homing has not",
    "WouldARouteRecoveryHelp": "it reads the error codes of Nav2's route server (a ROS action server), which homing "
                               "has not",
}

# py_trees' composites and decorators (for the README's table; homing reads no py_trees code).
PY_TREES: dict[str, tuple[str, str]] = {
    "Sequence(memory=True)": ("sequence", ""),
    "Sequence(memory=False)": ("reactive_sequence", ""),
    "Selector(memory=True)": ("fallback", ""),
    "Selector(memory=False)": ("reactive_fallback", ""),
    "Parallel(SuccessOnAll)": ("parallel: {success: all}", ""),
    "Parallel(SuccessOnOne)": ("parallel: {success: one, failure: 1}", "py_trees fails on the first failure"),
    "Parallel(SuccessOnSelected)": ("", "children are not named by role in homing; use success: N"),
    "Retry": ("retry", ""), "Repeat": ("repeat", ""), "Timeout": ("timeout", "adapter clock, not wall clock"),
    "Inverter": ("inverter", ""), "FailureIsSuccess": ("force_success", ""), "SuccessIsFailure": ("force_failure", ""),
    "RunningIsSuccess": ("running_is_success", ""), "RunningIsFailure": ("running_is_failure", ""),
    "SuccessIsRunning": ("success_is_running", ""), "FailureIsRunning": ("failure_is_running", ""),
    "OneShot": ("one_shot", ""), "EternalGuard": ("guard", "a condition subtree instead of a function"),
    "Condition(status)": ("failure_is_running / success_is_running", "wait for the wanted status"),
    "StatusToBlackboard": ("status_to_blackboard", ""), "PassThrough": ("", "a node that changes nothing: leave it out"),
    "Count": ("", "a debugging counter: the live view and run logs show every status change"),
    "idioms.pick_up_where_you_left_off": ("sequence_with_memory", ""),
    "idioms.either_or": ("switch", "on a blackboard value"),
    "idioms.oneshot": ("one_shot", ""),
}

PRE_POST_CONDITIONS = ("_skipIf", "_failureIf", "_successIf", "_while", "_onSuccess", "_onFailure", "_post", "_onHalted")
GROOT_ATTRS = ("_description", "_uid", "_fullpath", "_autoremap", "__shared_blackboard", "__autoremap")
