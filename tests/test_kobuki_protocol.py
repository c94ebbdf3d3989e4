"""Kobuki packets byte for byte against the protocol's rules, resynchronisation, and odometry through wrap-around."""

from __future__ import annotations

import math

import pytest
from homing.robot.hardware import kobuki_protocol as kp
from homing.robot.hardware.kobuki import KobukiOdometry, battery_state, charger_byte, ticks_delta
from homing.robot.types import ChargingSource, ChargingState


def test_base_control_packets_byte_for_byte() -> None:
    # Straight at 100 mm/s: headers, length 6 (id, size, 4 data bytes), speed 0x0064 LSB first, radius 0;
    # checksum 0x06 ^ 0x01 ^ 0x04 ^ 0x64 = 0x67.
    assert kp.speed_radius(0.1, 0.0) == (100, 0)
    assert kp.encode_packet([kp.base_control(100, 0)]) == bytes.fromhex("aa 55 06 01 04 64 00 00 00 67")
    # Turning in place at 1 rad/s: radius 1, speed ω·b/2 = 115 mm/s (0x73); checksum 06^01^04^73^01 = 0x71.
    assert kp.speed_radius(0.0, 1.0) == (115, 1)
    assert kp.encode_packet([kp.base_control(115, 1)]) == bytes.fromhex("aa 55 06 01 04 73 00 01 00 71")
    # Backwards at 0.25 m/s: −250 = 0xFF06 as a signed short, LSB first.
    assert kp.encode_packet([kp.base_control(*kp.speed_radius(-0.25, 0.0))]) == bytes.fromhex(
        "aa 55 06 01 04 06 ff 00 00" + f"{0x06 ^ 0x01 ^ 0x04 ^ 0x06 ^ 0xFF:02x}")


@pytest.mark.parametrize(("v", "w"), [(0.2, 0.5), (0.3, -0.4), (-0.2, 0.6), (0.05, 1.5), (0.3, 0.02)])
def test_speed_radius_is_the_outer_wheel_and_inverts(v: float, w: float) -> None:
    speed, radius = kp.speed_radius(v, w)
    r = 1000 * v / w
    assert radius == round(r)
    assert speed == round((r + 115 if r > 0 else r - 115) * w)  # kobuki_core: (R ± b/2)·ω [mm/s]
    left, right = kp.wheel_speeds(speed, radius)
    assert 0.5 * (left + right) == pytest.approx(v, abs=2e-3)
    assert (right - left) / kp.WHEEL_BIAS == pytest.approx(w, abs=1e-2)


def test_speed_radius_is_bounded_to_signed_shorts() -> None:
    assert kp.speed_radius(0.4, 0.01)[1] == 32767  # R = 40 m does not fit: DiffDrive::bound
    assert kp.speed_radius(-40.0, 0.0)[0] == -32768


def test_basic_sensor_data_decodes_a_worked_example() -> None:
    data = bytes.fromhex(
        "34 12"  # timestamp 0x1234 ms
        "05"  # bumpers: right (0x01) and left (0x04)
        "02 00"  # wheel drop: left; no cliff
        "fe ff 01 00"  # encoders: left 65534, right 1
        "fb 05"  # PWM −5 %, +5 %
        "01 06 a5 00"  # button B0; charger: docking, charging; battery 165 = 16.5 V; no over-current
    )
    basic = kp.BasicSensorData.decode(data)
    assert (basic.timestamp, basic.bumper, basic.wheel_drop, basic.cliff) == (0x1234, 5, 2, 0)
    assert (basic.left_encoder, basic.right_encoder, basic.left_pwm, basic.right_pwm) == (65534, 1, -5, 5)
    assert (basic.buttons, basic.charger, basic.voltage) == (1, kp.CHARGING, 16.5)
    assert basic.encode() == bytes((kp.BASIC_SENSOR_DATA, 15)) + data
    battery = battery_state(basic)
    assert battery.state is ChargingState.DOCKING_CHARGING and battery.source is ChargingSource.DOCK
    assert battery.percent == pytest.approx(100.0)
    inertia = kp.InertialSensor.decode(bytes.fromhex("28 23 9c ff 00 00 00"))  # 9000 = 90.00°, −100 = −1°/s
    assert inertia.heading == pytest.approx(math.pi / 2) and inertia.rate == pytest.approx(-math.pi / 180)


@pytest.mark.parametrize("charger", [0x00, 0x02, 0x06, 0x12, 0x16])
def test_charger_byte_round_trips(charger: int) -> None:
    state = battery_state(kp.BasicSensorData(charger=charger, battery=150))
    assert charger_byte(state) == charger
    assert state.voltage == 15.0 and state.percent == pytest.approx(95 * 1.8 / 3.3 + 5)


def _feedback(t: int, left: int, right: int, angle: int = 0) -> bytes:
    return kp.encode_packet([kp.BasicSensorData(timestamp=t, left_encoder=left, right_encoder=right).encode(),
                             kp.DockingIR(0, 2, 0).encode(), kp.InertialSensor(angle, 0).encode()])


def test_reader_skips_and_counts_garbage_bad_checksums_and_cut_packets() -> None:
    good = [_feedback(20 * k, k, k) for k in range(6)]
    bad = bytearray(good[1])
    bad[10] ^= 0x40  # one flipped bit: the XOR no longer cancels
    cut = good[3][:9]  # the line dropped the rest of this packet
    stream = b"\x00\x13\xaa\x37" + good[0] + bytes(bad) + good[2] + cut + good[4] + b"\xaa" + good[5]
    reader = kp.PacketReader()
    payloads = []
    for i in range(0, len(stream), 7):  # arrives in arbitrary chunks
        payloads += reader.feed(stream[i : i + 7])
    ts = [kp.BasicSensorData.decode(kp.split_sub_payloads(p)[0][0][1]).timestamp for p in payloads]
    assert ts == [0, 40, 80, 100]
    assert reader.stats.packets == 4
    assert reader.stats.checksum_errors == 2  # the flipped packet, and the cut one read across the next header
    assert reader.stats.resyncs == 4  # leading garbage, after each of the two bad packets, the stray 0xAA
    assert reader.stats.skipped > 4


def test_ticks_delta_wraps_both_ways() -> None:
    assert ticks_delta(100, 65500) == 136
    assert ticks_delta(65436, 0) == -100
    assert ticks_delta(0x8000 - 1, 0) == 0x7FFF


def test_odometry_through_encoder_and_gyro_wrap_around() -> None:
    odom = KobukiOdometry()
    per_tick = kp.TICK_TO_RAD * odom.wheel_radius
    start = 65000
    odom.update(kp.BasicSensorData(timestamp=65500, left_encoder=start, right_encoder=start), kp.InertialSensor(0))
    ticks, t = start, 65500
    for _ in range(300):  # 300 × 500 ticks: the counters wrap twice, the timestamp too
        ticks, t = (ticks + 500) & 0xFFFF, (t + 20) & 0xFFFF
        odom.update(kp.BasicSensorData(timestamp=t, left_encoder=ticks, right_encoder=ticks), kp.InertialSensor(0))
    assert odom.pose.x == pytest.approx(300 * 500 * per_tick, rel=1e-12)
    assert odom.pose.y == pytest.approx(0.0, abs=1e-12)
    assert odom.twist.v == pytest.approx(500 * per_tick / 0.020)
    # Turn in place to 179.5°, then back up 50 ticks twice across the gyro's ±180° wrap: facing −x,
    # backing up moves towards +x, along the mean headings 180° and −179.5°
    t = (t + 20) & 0xFFFF
    odom.update(kp.BasicSensorData(timestamp=t, left_encoder=ticks, right_encoder=ticks), kp.InertialSensor(17950))
    x0, y0 = odom.pose.x, odom.pose.y
    for angle in (-17950, -17950):
        ticks, t = (ticks - 50) & 0xFFFF, (t + 20) & 0xFFFF
        odom.update(kp.BasicSensorData(timestamp=t, left_encoder=ticks, right_encoder=ticks), kp.InertialSensor(angle))
    mids = (math.pi, math.radians(-179.5))
    assert odom.pose.x == pytest.approx(x0 - 50 * per_tick * sum(math.cos(m) for m in mids), rel=1e-9)
    assert odom.pose.y == pytest.approx(y0 - 50 * per_tick * sum(math.sin(m) for m in mids), abs=1e-12)
    assert odom.pose.theta == pytest.approx(math.radians(-179.5))


def test_the_emulated_base_answers_a_command_after_the_real_bases_dead_time() -> None:
    from homing.emulators.kobuki import DEAD_TIME, KobukiFirmware

    base = KobukiFirmware()
    assert DEAD_TIME == 0.2  # firmware 1.2.0, yujinrobot/kobuki#389
    base.receive(kp.encode_packet([kp.base_control(100, 0)]), now=1.0)  # straight at 0.1 m/s
    base.receive(kp.encode_packet([kp.base_control(115, 1)]), now=1.1)  # then in place at 1 rad/s
    assert base.velocity(1.19) == (0.0, 0.0)  # neither has reached the wheels yet
    assert base.velocity(1.2) == pytest.approx((0.1, 0.0))
    assert base.velocity(1.29) == pytest.approx((0.1, 0.0))
    v, w = base.velocity(1.3)
    assert v == pytest.approx(0.0, abs=1e-9) and w == pytest.approx(1.0, abs=0.005)  # 115 mm/s on a 230 mm bias
    assert base.commands == 2
