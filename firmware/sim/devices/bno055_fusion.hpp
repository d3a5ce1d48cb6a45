// The BNO055's sensor fusion, modelled from the motion's truth (issue 22 item 3; the devices'
// README). The part's orientation is tracked at 100 Hz from the motion: initialised from the
// specific force (the part at rest) and a configurable initial heading, then integrated from the
// angular rate, and pulled towards the measured gravity only while the part is still. The fusion
// outputs are that orientation with a small, slowly varying error (what a well-calibrated part
// shows); the magnetometer is the Earth field seen in the sensor frame; CALIB_STAT rises as a
// real part's does: the gyroscope after a few seconds still, the accelerometer over several
// still poses, the magnetometer over enough field directions. Portable C++14, no allocation.
//
// Frames: earth = north, west, up (right-handed); sensor = the part's (after AXIS_MAP_*). The
// quaternion rotates sensor vectors into the earth frame.
#pragma once

#include <stdint.h>

namespace ja {
namespace sim {

struct Quaternion {
  double w, x, y, z;
};

/// Euler angles in the BNO055's convention (degrees): heading clockwise from north about the
/// vertical, 0..360; roll about the sensor y axis, -90..90; pitch about the sensor x axis,
/// -180..180 (Windows orientation; the Android one reverses pitch). `q` as in Bno055Fusion.
void EulerFromQuaternion(const Quaternion& q, double* heading_deg, double* roll_deg,
                         double* pitch_deg);
/// The rotation with those angles (the inverse of EulerFromQuaternion).
Quaternion QuaternionFromEuler(double heading_deg, double roll_deg, double pitch_deg);
/// v (sensor frame) into the earth frame.
void RotateToEarth(const Quaternion& q, const double v[3], double out[3]);
/// v (earth frame) into the sensor frame.
void RotateToSensor(const Quaternion& q, const double v[3], double out[3]);

class Bno055Fusion {
 public:
  static constexpr uint64_t kStepNs = 10000000;  // 100 Hz

  /// Forget the orientation (aligned again at the next sample) and the calibration.
  void Reset();
  /// Forget the orientation only (the axis remap changed, or time jumped too far to follow).
  void Realign() { initialised_ = false; }
  /// Earth field (uT, north-west-up) and the heading of the part at the first sample (degrees).
  void set_earth_field(const double field_ut[3]) {
    for (int k = 0; k < 3; ++k) field_ut_[k] = field_ut[k];
  }
  void set_initial_heading_deg(double deg) { initial_heading_deg_ = deg; }
  const double* earth_field_ut() const { return field_ut_; }

  /// One step at device time t: specific force (m/s^2) and angular rate (rad/s, if any) in the
  /// sensor frame. `calibrate` says which of acc/gyr/mag the running fusion mode calibrates
  /// (bits 0, 1, 2).
  void Step(uint64_t t_ns, const double acc[3], const double gyr[3], bool has_gyro,
            uint8_t calibrate);

  bool initialised() const { return initialised_; }
  /// The tracked orientation (the truth, as well as the motion gives it).
  const Quaternion& orientation() const { return q_; }
  /// The orientation the part reports at t: the truth with the fusion's error; relative modes
  /// (`absolute` false) count heading from `heading0_deg`.
  Quaternion Reported(uint64_t t_ns, bool absolute, double heading0_deg) const;
  /// The Earth field in the sensor frame (uT) for the tracked orientation.
  void Magnetometer(double out_ut[3]) const { RotateToSensor(q_, field_ut_, out_ut); }
  /// CALIB_STAT levels 0..3 (`fast`: false in NDOF_FMC_OFF, more directions needed).
  uint8_t acc_level() const;
  uint8_t gyr_level() const { return gyr_level_; }
  uint8_t mag_level(bool fast) const;

 private:
  static constexpr uint64_t kGyroStillNs = 2000000000;  // a few seconds still
  static constexpr uint64_t kPoseStillNs = 1000000000;
  static constexpr int kMaxDirections = 16;

  bool AddDirection(double (*list)[3], int* n, const double v[3]) const;

  double field_ut_[3] = {20.0, 0.0, -45.0};  // mid-latitude: 20 uT north, 45 uT down
  double initial_heading_deg_ = 0.0;
  bool initialised_ = false;
  Quaternion q_{1, 0, 0, 0};
  uint64_t last_ns_ = 0;
  double last_w_[3] = {0, 0, 0};
  double last_a_[3] = {0, 0, 0};
  uint64_t still_ns_ = 0;
  uint8_t gyr_level_ = 0;
  bool pose_taken_ = false;
  double poses_[kMaxDirections][3];
  int pose_count_ = 0;
  double fields_[kMaxDirections][3];
  int field_count_ = 0;
};

}  // namespace sim
}  // namespace ja
