// Where the virtual sensors' readings come from: the specific force (m/s^2, sensor frame) and
// angular rate (rad/s) of one sensor as a function of device time. A track is one sensor's
// columns of an accelerations CSV (docs/design.md §4), linearly interpolated between rows.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include <vector>

namespace ja {
namespace sim {

struct MotionSample {
  double accel_mps2[3];
  double gyro_rps[3];
  bool has_gyro;
};

class MotionSource {
 public:
  /// The motion at device time t_ns; false if there is none (the device then reads zero).
  virtual bool Sample(uint64_t t_ns, MotionSample* out) const = 0;

 protected:
  ~MotionSource() = default;
};

/// A constant reading (static poses, unit tests).
class ConstantMotion final : public MotionSource {
 public:
  ConstantMotion() = default;
  ConstantMotion(double ax, double ay, double az) { Set(ax, ay, az); }
  void Set(double ax, double ay, double az);
  void SetGyro(double gx, double gy, double gz);
  bool Sample(uint64_t t_ns, MotionSample* out) const override;

 private:
  MotionSample s_{{0, 0, 0}, {0, 0, 0}, false};
};

/// One sensor's time series. Before the first row it holds the first row; after the last it
/// holds the last (or, with `loop`, wraps around with the table's period).
class MotionTrack final : public MotionSource {
 public:
  /// Appends a row; times must increase strictly. gyro may be null (no gyro columns).
  bool Append(double t_s, const double accel_mps2[3], const double* gyro_rps);
  void set_loop(bool loop) { loop_ = loop; }
  size_t rows() const { return t_s_.size(); }
  double duration_s() const { return t_s_.empty() ? 0.0 : t_s_.back() - t_s_.front(); }
  bool Sample(uint64_t t_ns, MotionSample* out) const override;

 private:
  std::vector<double> t_s_;
  std::vector<double> accel_;  // 3 per row
  std::vector<double> gyro_;   // 3 per row, or empty
  bool loop_ = false;
  mutable size_t hint_ = 0;  // last interval used: sequential sampling is O(1)
};

}  // namespace sim
}  // namespace ja
