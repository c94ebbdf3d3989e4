"""Perception: AprilTag detection and pose, camera model, scan preprocessing, dock IR decoding."""
