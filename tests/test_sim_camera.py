"""Rendered tags are read by pupil-apriltags with the right id and pose; frames only when a tag can be seen."""

from __future__ import annotations

import math

import numpy as np
import pupil_apriltags
import pytest
from homing.robot.types import Pose2
from homing.sim import Fault, SimRobot, load_world
from homing.sim.camera import CAMERA_POSE_XYZ


@pytest.fixture(scope="module")
def lab():
    return load_world("lab")


def _robot_facing(tag, distance: float, lateral: float = 0.0, yaw: float = 0.0) -> Pose2:
    """Base pose whose camera is ``distance`` in front of ``tag`` (``lateral`` to the side), turned by ``yaw``."""
    n = np.array([math.cos(tag.yaw), math.sin(tag.yaw)])
    side = np.array([-n[1], n[0]])
    cam = np.array([tag.x, tag.y]) + distance * n + lateral * side
    theta = tag.yaw + math.pi + yaw
    base = cam - CAMERA_POSE_XYZ[0] * np.array([math.cos(theta), math.sin(theta)])
    return Pose2(float(base[0]), float(base[1]), theta)


def _errors(image, pose: Pose2, tag):
    info = image.info
    det = pupil_apriltags.Detector(families="tag36h11")
    found = det.detect(image.grey(), estimate_tag_pose=True, camera_params=(info.fx, info.fy, info.cx, info.cy),
                       tag_size=tag.size)
    assert [d.tag_id for d in found] == [tag.id]
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    world_from_base = np.array([[c, -s, 0, pose.x], [s, c, 0, pose.y], [0, 0, 1, 0], [0, 0, 0, 1]])
    camera_from_tag = np.linalg.inv(world_from_base @ info.base_from_optical) @ tag.world_from_tag()
    d = found[0]
    t_err = float(np.linalg.norm(d.pose_t.ravel() - camera_from_tag[:3, 3]))
    R = d.pose_R.T @ camera_from_tag[:3, :3]
    r_err = math.degrees(math.acos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)))
    return t_err, r_err


def test_tag_at_one_metre_is_detected_with_its_pose(lab) -> None:
    tag = lab.tag(1)
    pose = _robot_facing(tag, 1.0)
    robot = SimRobot(lab, seed=3, start=pose)
    image = robot.observe().image
    assert image is not None and image.image.shape == (240, 320, 3)
    t_err, r_err = _errors(image, pose, tag)
    assert t_err < 0.02 and r_err < 2.0
    robot.close()


def test_oblique_tag_at_full_resolution(lab) -> None:
    tag = lab.tag(9)
    pose = _robot_facing(tag, 1.0, lateral=0.3, yaw=math.radians(10.0))  # viewed 17° off its axis
    robot = SimRobot(lab, seed=3, start=pose, image_size=(640, 480))
    t_err, r_err = _errors(robot.observe().image, pose, tag)
    assert t_err < 0.02 and r_err < 2.0
    robot.close()


def test_no_frame_without_a_tag_in_view_or_with_the_camera_off(lab) -> None:
    blank = Pose2(9.0, 7.0, math.pi)  # east room looking west: tags out of range or seen from behind
    robot = SimRobot(lab, seed=3, start=blank)
    assert robot.observe().image is None
    assert robot.render().image.shape == (240, 320, 3)  # a forced frame still renders
    robot.close()
    tag = lab.tag(1)
    robot = SimRobot(lab, seed=3, start=_robot_facing(tag, 1.5), faults=[Fault("camera_off", at=1.0, duration=2.0)])
    stamps = []
    for _ in range(40):
        obs = robot.observe()
        stamps.append((obs.stamp, obs.image is not None))
        robot.step(0.1)
    assert all(has for t, has in stamps if t < 1.0)
    assert not any(has for t, has in stamps if 1.0 + 1 / 3 <= t < 3.0)
    assert any(has for t, has in stamps if t >= 3.4)
    robot.close()


def test_tag_behind_a_wall_is_not_rendered(lab) -> None:
    # Tag 8 hangs on the partition's east face; from the west room the partition hides it.
    tag = lab.tag(8)
    behind = _robot_facing(tag, -1.0)  # 1 m behind the tag, through the partition, facing the same way
    behind = Pose2(behind.x, behind.y, tag.yaw + math.pi)
    assert lab.is_free(behind.x, behind.y)
    robot = SimRobot(lab, seed=3, start=behind)
    assert robot.camera.visible_tags(behind, [tag]) == []
    robot.close()
