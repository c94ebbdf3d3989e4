"""Lidar loop closures between keyframes: point-to-line ICP (Censi, ICRA 2008) with a degeneracy-aware covariance.

The tags close loops only where the camera sees a tag (within 3 m, facing
it); a large world's stretches between tags are tied together by odometry
alone, whose encoder slip (≈ 4 cm σ per 8 m) and heading drift bend the
map between its tags — aligned on the dock's tag, the whole map then moves.
The 360° lidar sees the same walls every time the robot passes a place, so
when a new keyframe lies within ``radius`` of an old one (by the map's
current estimate), their scans are matched and the relative pose becomes a
robust between-factor in :class:`homing.mapping.landmark_slam.LandmarkSlam`.

The match's covariance is ``σ²·(JᵀJ)⁻¹`` of the point-to-line residuals
(Censi 2007). In a straight corridor that matrix claims ~1 cm along the
corridor from the lidar noise in the wall normals, while the true error
there is 10–30 cm (measured on ``homing bench slam``'s loop world: matches
whose weaker position direction has σ > ``DEGENERATE`` all slid along a
corridor). Such a direction is given ``FREE_SIGMA``: the closure then fixes
the heading and the across-corridor offset only, which it measures to
≈ 0.02° and ≈ 1 cm.

Frames: points are (N, 2) arrays in a keyframe's ``base_link`` [m]; a match
returns the current keyframe's pose in the old one's frame, and its
covariance is in the old one's frame too. A GTSAM ``BetweenFactorPose2``
measures its error in the *measured* pose's frame, so the covariance must
be rotated by the match's heading first
(:func:`homing.mapping.landmark_slam.lidar_factor`): used unrotated, a
corridor's free axis and its tight one swap when the two passes cross at an
angle, and position closures pulled whole corridors along their axis (why
landmark SLAM once kept only their heading). Not for: scans
from far-apart places (no global search: the guess must be within ~0.3 m
and ~10°), or worlds of bare parallel walls only (every match degenerate).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from homing.robot.types import Pose2
from scipy.spatial import cKDTree

NORMAL_NEIGHBOURS = 6  # points whose spread gives a reference point's normal
MAX_FLATNESS = 0.1  # smallest/largest spread of those neighbours: above it the point is not on a line
GATES = (0.5, 0.3, 0.2, 0.1)  # [m] correspondence distance, tightened every GATE_ITERATIONS
GATE_ITERATIONS = 5
MAX_ITERATIONS = 30
MIN_ITERATIONS = 15  # before convergence is accepted (the gates must have tightened)
CONVERGED = 1e-5  # [m, rad] step below which the match has converged
HUBER = 0.03  # [m] residual beyond which a pair's weight falls as 1/|r|
MIN_PAIRS = 20  # fewer matched points: no match
MIN_OVERLAP = 0.5  # share of the current scan's points that must be matched
MAX_RMS = 0.03  # [m] residual of an accepted match (lidar σ ≈ 1 cm)
SIGMA_MIN = (0.01, math.radians(0.1))  # [m, rad] floors: the lidar's range noise, its angular step
DEGENERATE = 0.005  # [m] a position direction claimed weaker than this is a corridor's axis
FREE_SIGMA = 1.0  # [m] σ given to that direction: the match says nothing along it


@dataclass(frozen=True)
class Reference:
    """An old keyframe's scan ready to be matched against: its points (N, 2), their normals (N, 2), a k-d tree."""

    points: np.ndarray
    normals: np.ndarray
    on_line: np.ndarray  # (N,) bool: the point's neighbours lie on a line (a usable normal)
    tree: cKDTree


@dataclass(frozen=True)
class Match:
    """A converged match: ``pose`` of the current frame in the reference frame, its (3, 3) covariance, fit stats."""

    pose: Pose2
    covariance: np.ndarray  # (3, 3) of (x, y, θ) in the reference frame [m², rad²], degenerate axes freed
    rms: float  # [m] point-to-line residual
    overlap: float  # share of the current points matched


def reference(points: np.ndarray) -> Reference:
    """Normals of (N, 2) points [m] from their ``NORMAL_NEIGHBOURS`` nearest (smallest principal axis)."""
    tree = cKDTree(points)
    k = min(NORMAL_NEIGHBOURS, len(points))
    _, idx = tree.query(points, k=k)
    nb = points[idx] - points[idx].mean(axis=1, keepdims=True)
    # The spread [[a, b], [b, c]] of each neighbourhood, its eigenvalues and principal axis in closed form
    # (numpy's batched eigh costs ten times more).
    a = np.einsum("nk,nk->n", nb[..., 0], nb[..., 0])
    b = np.einsum("nk,nk->n", nb[..., 0], nb[..., 1])
    c = np.einsum("nk,nk->n", nb[..., 1], nb[..., 1])
    half, root = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    flat = (half - root) / np.maximum(half + root, 1e-12)
    axis = 0.5 * np.arctan2(2.0 * b, a - c)  # the line's direction; the normal is across it
    normals = np.column_stack([-np.sin(axis), np.cos(axis)])
    return Reference(points, normals, flat < MAX_FLATNESS, tree)


def merge(references: Sequence[Reference], poses: Sequence[Pose2]) -> Reference:
    """One reference of several scans' references, each moved by its pose (their frame in the common one).

    The normals stay those of each scan alone: a local map of many scans is
    matched without recomputing them (only the k-d tree is built anew).
    """
    points, normals = [], []
    for ref, pose in zip(references, poses, strict=True):
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        rot = np.array([[c, s], [-s, c]])  # row vectors times rot = rotated by θ
        points.append(ref.points @ rot + np.array([pose.x, pose.y]))
        normals.append(ref.normals @ rot)
    pts = np.vstack(points)
    return Reference(pts, np.vstack(normals), np.concatenate([r.on_line for r in references]), cKDTree(pts))


def match(ref: Reference, points: np.ndarray, guess: Pose2, position: bool = True,
          max_rms: float = MAX_RMS, gates: tuple[float, ...] = GATES, min_overlap: float = MIN_OVERLAP,
          min_iterations: int = MIN_ITERATIONS, converged: float = CONVERGED,
          floor: tuple[float, float] = SIGMA_MIN) -> Match | None:
    """Pose of the frame of ``points`` (M, 2) [m] in ``ref``'s frame, starting from ``guess``; None if it fails.

    Gauss–Newton on point-to-line distances with Huber weights, the
    correspondence gate shrinking through ``gates`` [m] (0.5 to 0.1 m: scans
    sampled densely, as the RPLIDAR's indoors; a sparser scan's points lie
    farther apart along a wall and need a wider last gate). Fails on too
    few pairs, an overlap under ``min_overlap`` or a residual above
    ``max_rms`` [m]. ``position`` False:
    the covariance frees both position axes (a heading-only closure).
    ``min_iterations``: steps before convergence counts, ``converged``
    [m, rad] the step that counts as converged (fewer and coarser for a
    refinement from a pose already within a few centimetres); ``floor``
    ([m], [rad]) the covariance's floors (see :func:`covariance`).
    """
    if len(ref.points) < MIN_PAIRS or len(points) < MIN_PAIRS:
        return None
    x = np.array([guess.x, guess.y, guess.theta])
    last = len(ref.points) - 1
    for it in range(MAX_ITERATIONS):
        gate = gates[min(it // GATE_ITERATIONS, len(gates) - 1)]
        c, s = math.cos(x[2]), math.sin(x[2])
        moved = points @ np.array([[c, s], [-s, c]]) + x[:2]
        dist, j = ref.tree.query(moved, distance_upper_bound=gate)
        ok = np.isfinite(dist)
        ok[ok] = ref.on_line[np.minimum(j[ok], last)]
        if ok.sum() < MIN_PAIRS:
            return None
        n, p = ref.normals[j[ok]], points[ok]
        r = np.einsum("ij,ij->i", n, moved[ok] - ref.points[j[ok]])
        d_theta = np.column_stack([-s * p[:, 0] - c * p[:, 1], c * p[:, 0] - s * p[:, 1]])
        J = np.column_stack([n, np.einsum("ij,ij->i", n, d_theta)])
        w = 1.0 / np.maximum(1.0, np.abs(r) / HUBER)
        step = -np.linalg.solve(J.T @ (J * w[:, None]) + 1e-9 * np.eye(3), J.T @ (w * r))
        x += step
        if it >= min_iterations and np.abs(step).max() < converged:
            break
    rms = float(np.sqrt(np.mean(r**2)))
    overlap = float(ok.mean())
    if rms > max_rms or overlap < min_overlap:
        return None
    return Match(Pose2(float(x[0]), float(x[1]), float(x[2])), covariance(J, rms, position, floor), rms, overlap)


def covariance_at(ref: Reference, points: np.ndarray, pose: Pose2, gate: float = GATES[-1]) -> np.ndarray | None:
    """(3, 3) covariance of ``pose`` (the frame of ``points`` (M, 2) [m] in ``ref``'s) as :func:`covariance` gives it.

    For a pose found by another matcher (the correlative search): the
    point-to-line Jacobian at ``pose`` alone, pairs within ``gate`` [m];
    None with fewer than ``MIN_PAIRS`` pairs.
    """
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    moved = points @ np.array([[c, s], [-s, c]]) + np.array([pose.x, pose.y])
    dist, j = ref.tree.query(moved, distance_upper_bound=gate)
    ok = np.isfinite(dist)
    ok[ok] = ref.on_line[np.minimum(j[ok], len(ref.points) - 1)]
    if ok.sum() < MIN_PAIRS:
        return None
    n, p = ref.normals[j[ok]], points[ok]
    r = np.einsum("ij,ij->i", n, moved[ok] - ref.points[j[ok]])
    d_theta = np.column_stack([-s * p[:, 0] - c * p[:, 1], c * p[:, 0] - s * p[:, 1]])
    J = np.column_stack([n, np.einsum("ij,ij->i", n, d_theta)])
    return covariance(J, float(np.sqrt(np.mean(r**2))))


def covariance(J: np.ndarray, rms: float, position: bool = True,
               floor: tuple[float, float] = SIGMA_MIN) -> np.ndarray:
    """(3, 3) covariance of a match from its (K, 3) residual Jacobian, floored, with degenerate position axes freed.

    ``position`` False frees both position axes. ``floor`` ([m], [rad]): the
    σ below which no position axis and no heading is claimed (default
    ``SIGMA_MIN``; a short match between neighbouring keyframes, whose
    errors were measured, may be given that measured floor instead). The heading–position cross
    terms are dropped: a freed axis would otherwise drag the heading's
    variance with it.
    """
    cov = max(rms, SIGMA_MIN[0]) ** 2 * np.linalg.inv(J.T @ J)  # the residual's σ: the lidar's noise at least
    w, v = np.linalg.eigh(cov[:2, :2])
    sigma = np.sqrt(np.maximum(w, 0.0))
    sigma = np.where((sigma > DEGENERATE) | (not position), FREE_SIGMA, np.maximum(sigma, floor[0]))
    out = np.zeros((3, 3))
    out[:2, :2] = v @ np.diag(sigma**2) @ v.T
    out[2, 2] = max(float(cov[2, 2]), floor[1] ** 2)
    return out


def nearest_old(positions: np.ndarray, here: np.ndarray, radius: float, min_gap: int) -> int | None:
    """Index of the keyframe nearest ``here`` (2,) [m] within ``radius`` among all but the last ``min_gap``.

    ``positions`` is (N, 2) [m] in ``map``, in keyframe order; the gap keeps
    a closure from merely repeating the odometry of the last few metres.
    """
    old = positions[: max(len(positions) - min_gap, 0)]
    if len(old) == 0:
        return None
    d = np.hypot(old[:, 0] - here[0], old[:, 1] - here[1])
    i = int(np.argmin(d))
    return i if d[i] < radius else None
