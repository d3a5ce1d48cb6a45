#include "sim/devices/bno055_fusion.hpp"

#include <cmath>

namespace ja {
namespace sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr double kG = 9.80665;
constexpr double kStillRateRps = 0.02;        // |w| below: still
constexpr double kStillAccelMps2 = 0.2;       // | |a| - g | below: still
constexpr double kStillStepMps2 = 0.3;        // and a changing less than this a step
constexpr double kTiltGainPerS = 2.0;         // correction towards gravity while still, 1/s
constexpr double kTiltGainNoGyroPerS = 10.0;  // and without rates, always
constexpr double kMinSeparationCos = 0.8660254037844387;  // 30 degrees between directions

Quaternion Mul(const Quaternion& a, const Quaternion& b) {
  return {
      a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
      a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

Quaternion Normalised(const Quaternion& q) {
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  if (!(n > 0)) return {1, 0, 0, 0};
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

// exp of a rotation vector r (rad): the rotation by |r| about r.
Quaternion FromRotationVector(double rx, double ry, double rz) {
  const double a = std::sqrt(rx * rx + ry * ry + rz * rz);
  if (a < 1e-12) return Normalised({1, rx / 2, ry / 2, rz / 2});
  const double s = std::sin(a / 2) / a;
  return {std::cos(a / 2), rx * s, ry * s, rz * s};
}

double Norm(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
}  // namespace

void RotateToEarth(const Quaternion& q, const double v[3], double out[3]) {
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  out[0] =
      (1 - 2 * (y * y + z * z)) * v[0] + 2 * (x * y - w * z) * v[1] + 2 * (x * z + w * y) * v[2];
  out[1] =
      2 * (x * y + w * z) * v[0] + (1 - 2 * (x * x + z * z)) * v[1] + 2 * (y * z - w * x) * v[2];
  out[2] =
      2 * (x * z - w * y) * v[0] + 2 * (y * z + w * x) * v[1] + (1 - 2 * (x * x + y * y)) * v[2];
}

void RotateToSensor(const Quaternion& q, const double v[3], double out[3]) {
  RotateToEarth({q.w, -q.x, -q.y, -q.z}, v, out);
}

void EulerFromQuaternion(const Quaternion& q, double* heading_deg, double* roll_deg,
                         double* pitch_deg) {
  // R = Rz(yaw) Ry(roll) Rx(pitch), yaw counter-clockwise; heading = -yaw.
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  const double r20 = 2 * (x * z - w * y);
  const double r21 = 2 * (y * z + w * x), r22 = 1 - 2 * (x * x + y * y);
  const double r10 = 2 * (x * y + w * z), r00 = 1 - 2 * (y * y + z * z);
  const double s = r20 > 1 ? 1 : r20 < -1 ? -1 : r20;
  *roll_deg = std::asin(-s) / kDeg;
  *pitch_deg = std::atan2(r21, r22) / kDeg;
  double heading = -std::atan2(r10, r00) / kDeg;
  if (heading < 0) heading += 360.0;
  if (heading >= 360.0) heading -= 360.0;
  *heading_deg = heading;
}

Quaternion QuaternionFromEuler(double heading_deg, double roll_deg, double pitch_deg) {
  const double yaw = -heading_deg * kDeg, roll = roll_deg * kDeg, pitch = pitch_deg * kDeg;
  const Quaternion qz{std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)};
  const Quaternion qy{std::cos(roll / 2), 0, std::sin(roll / 2), 0};
  const Quaternion qx{std::cos(pitch / 2), std::sin(pitch / 2), 0, 0};
  return Mul(Mul(qz, qy), qx);
}

void Bno055Fusion::Reset() {
  initialised_ = false;
  q_ = {1, 0, 0, 0};
  still_ns_ = 0;
  pose_taken_ = false;
  pose_count_ = field_count_ = 0;
  gyr_level_ = 0;
}

bool Bno055Fusion::AddDirection(double (*list)[3], int* n, const double v[3]) const {
  const double norm = Norm(v);
  if (!(norm > 0) || *n >= kMaxDirections) return false;
  const double u[3] = {v[0] / norm, v[1] / norm, v[2] / norm};
  for (int i = 0; i < *n; ++i) {
    if (list[i][0] * u[0] + list[i][1] * u[1] + list[i][2] * u[2] > kMinSeparationCos) return false;
  }
  for (int k = 0; k < 3; ++k) list[*n][k] = u[k];
  ++*n;
  return true;
}

void Bno055Fusion::Step(uint64_t t_ns, const double acc[3], const double gyr[3], bool has_gyro,
                        uint8_t calibrate) {
  const double a_norm = Norm(acc);
  const double w[3] = {has_gyro ? gyr[0] : 0.0, has_gyro ? gyr[1] : 0.0, has_gyro ? gyr[2] : 0.0};
  const double da[3] = {acc[0] - last_a_[0], acc[1] - last_a_[1], acc[2] - last_a_[2]};
  const bool still = Norm(w) < kStillRateRps && std::fabs(a_norm - kG) < kStillAccelMps2 &&
                     Norm(da) < kStillStepMps2;
  for (int k = 0; k < 3; ++k) last_a_[k] = acc[k];
  if (!initialised_) {
    if (!(a_norm > 0)) return;  // no motion: nothing to align to
    // At rest the specific force points up: roll and pitch from it, heading as configured.
    const double u[3] = {acc[0] / a_norm, acc[1] / a_norm, acc[2] / a_norm};
    const double roll = std::asin(u[0] > 1 ? -1 : u[0] < -1 ? 1 : -u[0]) / kDeg;
    const double pitch = std::atan2(u[1], u[2]) / kDeg;
    q_ = QuaternionFromEuler(initial_heading_deg_, roll, pitch);
    initialised_ = true;
    last_ns_ = t_ns;
    for (int k = 0; k < 3; ++k) last_w_[k] = w[k];
    return;
  }
  const double dt = static_cast<double>(t_ns - last_ns_) * 1e-9;
  last_ns_ = t_ns;
  // The rate over the step: the mean of its ends (the motion is linear between rows).
  double r[3];
  for (int k = 0; k < 3; ++k) r[k] = 0.5 * (w[k] + last_w_[k]) * dt;
  for (int k = 0; k < 3; ++k) last_w_[k] = w[k];
  // Towards the measured up while still; always, and faster, when the motion has no rates (the
  // specific force is then all there is to follow).
  if ((still || !has_gyro) && a_norm > 0) {
    const double gain = has_gyro ? kTiltGainPerS : kTiltGainNoGyroPerS;
    // e = a x v (v the up the orientation predicts), body frame.
    const double up[3] = {0, 0, 1};
    double v[3];
    RotateToSensor(q_, up, v);
    const double a[3] = {acc[0] / a_norm, acc[1] / a_norm, acc[2] / a_norm};
    const double e[3] = {a[1] * v[2] - a[2] * v[1], a[2] * v[0] - a[0] * v[2],
                         a[0] * v[1] - a[1] * v[0]};
    for (int k = 0; k < 3; ++k) r[k] += gain * e[k] * dt;
  }
  q_ = Normalised(Mul(q_, FromRotationVector(r[0], r[1], r[2])));

  // Calibration (only what the running fusion mode calibrates).
  still_ns_ = still ? still_ns_ + static_cast<uint64_t>(dt * 1e9 + 0.5) : 0;
  if (!still) pose_taken_ = false;
  if (calibrate & 2u) {
    const uint8_t level = still_ns_ >= kGyroStillNs       ? 3
                          : still_ns_ >= kGyroStillNs / 2 ? 2
                          : still_ns_ >= kGyroStillNs / 4 ? 1
                                                          : 0;
    if (level > gyr_level_) gyr_level_ = level;
  }
  if ((calibrate & 1u) && still_ns_ >= kPoseStillNs && !pose_taken_) {
    AddDirection(poses_, &pose_count_, acc);
    pose_taken_ = true;
  }
  if (calibrate & 4u) {
    double b[3];
    Magnetometer(b);
    AddDirection(fields_, &field_count_, b);
  }
}

Quaternion Bno055Fusion::Reported(uint64_t t_ns, bool absolute, double heading0_deg) const {
  // A well-calibrated part's error: a few tenths of a degree, slowly varying.
  const double t = static_cast<double>(t_ns) * 1e-9;
  const double ex = 0.15 * kDeg * std::sin(2 * kPi * t / 7.3);
  const double ey = 0.15 * kDeg * std::sin(2 * kPi * t / 11.1 + 1.0);
  const double ez = (absolute ? 0.4 : 0.25) * kDeg * std::sin(2 * kPi * t / 17.9 + 2.0);
  Quaternion q = Mul(q_, FromRotationVector(ex, ey, ez));
  if (!absolute) {
    const double a = heading0_deg * kDeg;  // counter-clockwise by heading0: heading - heading0
    q = Mul(Quaternion{std::cos(a / 2), 0, 0, std::sin(a / 2)}, q);
  }
  return Normalised(q);
}

uint8_t Bno055Fusion::acc_level() const {
  return pose_count_ >= 6 ? 3 : pose_count_ >= 3 ? 2 : pose_count_ >= 1 ? 1 : 0;
}

uint8_t Bno055Fusion::mag_level(bool fast) const {
  const int step = fast ? 2 : 3;  // NDOF_FMC_OFF: fast magnetometer calibration off
  const int n = field_count_ / step;
  return static_cast<uint8_t>(n > 3 ? 3 : n);
}

}  // namespace sim
}  // namespace ja
