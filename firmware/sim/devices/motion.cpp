#include "sim/devices/motion.hpp"

#include <cmath>

namespace ja {
namespace sim {

void ConstantMotion::Set(double ax, double ay, double az) {
  s_.accel_mps2[0] = ax;
  s_.accel_mps2[1] = ay;
  s_.accel_mps2[2] = az;
}

void ConstantMotion::SetGyro(double gx, double gy, double gz) {
  s_.gyro_rps[0] = gx;
  s_.gyro_rps[1] = gy;
  s_.gyro_rps[2] = gz;
  s_.has_gyro = true;
}

bool ConstantMotion::Sample(uint64_t /*t_ns*/, MotionSample* out) const {
  *out = s_;
  return true;
}

bool MotionTrack::Append(double t_s, const double accel_mps2[3], const double* gyro_rps) {
  if (!t_s_.empty() && !(t_s > t_s_.back())) return false;
  if (!t_s_.empty() && (gyro_rps != nullptr) != !gyro_.empty()) return false;
  t_s_.push_back(t_s);
  accel_.insert(accel_.end(), accel_mps2, accel_mps2 + 3);
  if (gyro_rps) gyro_.insert(gyro_.end(), gyro_rps, gyro_rps + 3);
  return true;
}

bool MotionTrack::Sample(uint64_t t_ns, MotionSample* out) const {
  const size_t n = t_s_.size();
  if (n == 0) return false;
  double t = static_cast<double>(t_ns) * 1e-9;
  if (loop_ && n > 1 && t > t_s_.back()) {
    // Wrap with period = duration + one row interval, so the last row is not repeated.
    const double period = duration_s() + (t_s_[n - 1] - t_s_[n - 2]);
    t = t_s_.front() + std::fmod(t - t_s_.front(), period);
  }
  size_t i0 = 0;
  double w = 0.0;  // weight of row i0 + 1
  if (t <= t_s_.front()) {
    i0 = 0;
  } else if (t >= t_s_.back()) {
    i0 = n - 1;
  } else {
    size_t i = hint_ < n - 1 ? hint_ : 0;
    if (!(t_s_[i] <= t && t < t_s_[i + 1])) {
      size_t lo = 0, hi = n - 1;  // t_s_[lo] <= t < t_s_[hi]
      while (hi - lo > 1) {
        const size_t mid = lo + (hi - lo) / 2;
        (t_s_[mid] <= t ? lo : hi) = mid;
      }
      i = lo;
    }
    hint_ = i;
    i0 = i;
    w = (t - t_s_[i]) / (t_s_[i + 1] - t_s_[i]);
  }
  const size_t i1 = w > 0.0 ? i0 + 1 : i0;
  for (int k = 0; k < 3; ++k) {
    out->accel_mps2[k] = accel_[3 * i0 + k] + w * (accel_[3 * i1 + k] - accel_[3 * i0 + k]);
    out->gyro_rps[k] =
        gyro_.empty() ? 0.0 : gyro_[3 * i0 + k] + w * (gyro_[3 * i1 + k] - gyro_[3 * i0 + k]);
  }
  out->has_gyro = !gyro_.empty();
  return true;
}

}  // namespace sim
}  // namespace ja
