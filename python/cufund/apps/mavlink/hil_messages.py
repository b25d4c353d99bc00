"""cufund sensor messages -> PX4's simulator MAVLink messages (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION).

Units and bits are PX4's ``simulator_mavlink`` contract: accelerations [m/s^2] and rates [rad/s] in body FRD,
magnetic field [gauss] in body FRD, ``abs_pressure`` [hPa], ``pressure_alt`` [m] (ISA), ``temperature`` [degC];
``fields_updated`` says which groups are new in this message. Every frame change goes through
:mod:`cufund.apps.mavlink.frames`.
"""

from __future__ import annotations

import numpy as np

from cufund.core.messages import AirPressure, GpsFix, Imu, MagneticField, Odometry
from cufund.geometry import quat_to_matrix
from cufund.sensors.barometer import isa_altitude

from . import frames
from .hil_codec import FrameWriter

__all__ = ["HIL_ACCEL", "HIL_BARO", "HIL_GYRO", "HIL_MAG", "TESLA_TO_GAUSS", "HilEncoder"]

HIL_ACCEL = 0x0007  #: xacc, yacc, zacc
HIL_GYRO = 0x0038  #: xgyro, ygyro, zgyro
HIL_MAG = 0x01C0  #: xmag, ymag, zmag
HIL_BARO = 0x1A00  #: abs_pressure (0x200), pressure_alt (0x800), temperature (0x1000)
TESLA_TO_GAUSS = 1e4
GPS_FIX_TYPE_NO_FIX = 1


class HilEncoder:
    """Encodes the latest cufund samples as MAVLink 2 frames (bytes) with ``writer`` (a
    :class:`~cufund.apps.mavlink.hil_codec.FrameWriter`: HIL_SENSOR and HIL_GPS are packed by hand, byte-identical to
    pymavlink's encoder).

    ``q_BI``: the IMU's mounting (IMU frame to body, [w, x, y, z]); its samples are rotated into the body frame.
    ``origin``: the world origin's geodetic position (HIL_STATE_QUATERNION's lat/lon/alt).
    ``sensor_id``: HIL_SENSOR/HIL_GPS ``id`` (PX4 steps its lockstep clock on id 0, the primary IMU).
    """

    def __init__(
        self, writer: FrameWriter, origin: frames.GeodeticOrigin, q_BI: np.ndarray | None = None, sensor_id: int = 0
    ) -> None:
        self.writer = writer
        self.origin = origin
        q = np.asarray((1.0, 0.0, 0.0, 0.0) if q_BI is None else q_BI, dtype=float)
        self.R_BI = None if np.allclose(q, (1.0, 0.0, 0.0, 0.0)) else quat_to_matrix(q)
        if isinstance(sensor_id, bool) or not isinstance(sensor_id, int) or not 0 <= sensor_id <= 255:
            raise ValueError(f"sensor_id must be an integer in [0, 255], got {sensor_id!r}")
        self.sensor_id = sensor_id
        self._imu = (0.0,) * 6  # accel, gyro in FRD, as sent
        self._mag = (0.0,) * 3  # FRD [gauss]
        self._baro = (0.0, 0.0, 0.0)

    def hil_sensor(
        self, time_usec: int, imu: Imu | None, mag: MagneticField | None, baro: AirPressure | None
    ) -> tuple[bytes, int]:
        """(HIL_SENSOR frame, its ``fields_updated``): the groups whose sample is given are marked (the others
        repeat their last values, as Gazebo does, with their bits clear)."""
        bits = 0
        if imu is not None:
            f, w = imu.f_I, imu.w_I
            if self.R_BI is not None:
                f, w = self.R_BI @ f, self.R_BI @ w
            fx, fy, fz = f.tolist()
            wx, wy, wz = w.tolist()
            self._imu = frames.flu_to_frd_xyz(fx, fy, fz) + frames.flu_to_frd_xyz(wx, wy, wz)
            bits = HIL_ACCEL | HIL_GYRO
        if mag is not None:
            mx, my, mz = frames.flu_to_frd_xyz(*mag.m_B.tolist())
            self._mag = (mx * TESLA_TO_GAUSS, my * TESLA_TO_GAUSS, mz * TESLA_TO_GAUSS)
            bits |= HIL_MAG
        if baro is not None:
            p = float(baro.pressure_pa)
            self._baro = (p / 100.0, float(isa_altitude(p)), float(baro.temperature_k) - 273.15)
            bits |= HIL_BARO
        ax, ay, az, gx, gy, gz = self._imu
        mx, my, mz = self._mag
        hpa, alt, temp_c = self._baro
        return self.writer.hil_sensor(
            time_usec, ax, ay, az, gx, gy, gz, mx, my, mz, hpa, 0.0, alt, temp_c, bits, self.sensor_id
        ), bits

    def hil_gps(self, time_usec: int, fix: GpsFix) -> bytes:
        """HIL_GPS of a fix (degE7, mm, cm/s NED, eph/epv cm, cog cdeg); no fix -> fix_type 1, unknowns."""
        unknown = frames.UINT16_UNKNOWN
        if fix.fix_type < 2 or not np.isfinite(fix.latitude_deg):
            return self.writer.hil_gps(
                time_usec,
                GPS_FIX_TYPE_NO_FIX,
                0,
                0,
                0,
                unknown,
                unknown,
                unknown,
                0,
                0,
                0,
                unknown,
                int(fix.satellites),
                self.sensor_id,
            )
        v_N = frames.enu_to_ned(fix.v_W)
        vn, ve, vd = (int(x) for x in frames.m_s_to_cm_s(v_N))
        return self.writer.hil_gps(
            time_usec,
            int(fix.fix_type),
            frames.deg_to_e7(fix.latitude_deg),
            frames.deg_to_e7(fix.longitude_deg),
            frames.m_to_mm(fix.altitude_m),
            frames.m_to_cm_u16(fix.eph),
            frames.m_to_cm_u16(fix.epv),
            frames.m_to_cm_u16(float(np.hypot(v_N[0], v_N[1]))),
            vn,
            ve,
            vd,
            frames.course_cdeg(v_N),
            int(fix.satellites),
            self.sensor_id,
        )

    def hil_state_quaternion(self, time_usec: int, truth: Odometry) -> bytes:
        """HIL_STATE_QUATERNION (ground truth): attitude NED/FRD, body rates FRD, position degE7/mm, velocity
        NED cm/s, airspeed cm/s (still air), body FRD acceleration [mG] (kinematic, gravity excluded)."""
        q = frames.q_enu_flu_to_ned_frd(truth.q_WB)
        p, r, y = frames.rates_flu_to_frd(truth.w_B)
        lat, lon, alt = self.origin.enu_to_lla(truth.p_W)
        vx, vy, vz = frames.m_s_to_cm_s(frames.enu_to_ned(truth.v_W))
        a_W = truth.a_W if truth.a_W is not None else np.zeros(3)
        a_B = frames.flu_to_frd(quat_to_matrix(truth.q_WB).T @ a_W)
        ax, ay, az = frames.m_s2_to_mg(a_B)
        speed = frames.m_to_cm_u16(float(np.linalg.norm(truth.v_W)))
        return self.writer.pack(
            self.writer.mav.hil_state_quaternion_encode(
                time_usec,
                [float(x) for x in q],
                float(p),
                float(r),
                float(y),
                frames.deg_to_e7(lat),
                frames.deg_to_e7(lon),
                frames.m_to_mm(alt),
                int(vx),
                int(vy),
                int(vz),
                speed,
                speed,
                int(ax),
                int(ay),
                int(az),
            )
        )
