// One configured accelerometer at run time: its driver (constructed in place, no heap), its bus
// (a TCA9548A channel or the bus itself), the calibration folded into fixed point, and the fault
// bookkeeping behind the per-sensor status bits (APP.md, "Faults").
#pragma once

#include <stdint.h>

#include "app/app_config.hpp"
#include "drivers/adxl345.hpp"
#include "drivers/adxl357.hpp"
#include "drivers/bno055.hpp"
#include "drivers/i2c_bus.hpp"
#include "protocol/messages.hpp"

namespace ja {
namespace app {

/// Link-frame x, y of one sensor after calibration and mounting rotation, Q15.16 m/s^2 raw
/// (the filter's FixedPolicy::Accel).
struct LinkReading {
  int32_t x_q16, y_q16;
};

/// Calibration, count scale and mounting rotation folded into one 2x3 map (configuration time):
/// [x, y]_link = M counts + b, M = R(rot)[rows 0-1] S diag(scale) in Q30, b = R(rot)[rows 0-1] o
/// in Q16. One rounding per axis (APP.md gives the formula the host mirrors).
struct CalibrationMap {
  int32_t m_q30[2][3];
  int32_t b_q16[2];
  bool saturated;  // a coefficient did not fit Q1.30 (|M| >= 2): the map is unusable
  /// b 2^14 - 2^15 sum_j M_rj as a 64-bit {lo, hi} (core::detail::Wide): the constant part of
  /// the 16-bit-count path (ApplyCalibration), formed once at configuration.
  uint32_t base_lo[2];
  int32_t base_hi[2];
};

/// Derives the map of a sensor (float arithmetic, configuration time only).
CalibrationMap MakeCalibrationMap(const SensorConfig& s, const Calibration& k);
/// Applies the map to raw counts; increments *saturations when a result saturates Q15.16.
/// Counts that fit 16 bits (ADXL345, BNO055 always) take 32 x 16-bit products, the others
/// ApplyCalibrationWide: the same sum exactly, so the same values and saturations.
LinkReading ApplyCalibration(const CalibrationMap& map, const drivers::RawSample& counts,
                             uint16_t* saturations);
/// The reference: 32 x 32-bit products (APP.md's formula).
LinkReading ApplyCalibrationWide(const CalibrationMap& map, const drivers::RawSample& counts,
                                 uint16_t* saturations);

/// m/s^2 per count of a model at a range (the drivers' datasheet scales).
float Mps2PerCount(uint8_t model, uint8_t range_g);
/// Counts at or beyond which an axis reads as saturated: nominal full scale minus one count.
int32_t SaturationCounts(uint8_t model, uint8_t range_g);

/// The bus a sensor's driver talks to. Normally it forwards to the sensor's bus; for the
/// asynchronous batch (hal.hpp, I2cBatch) it first records the driver's sample read without
/// touching the bus (capture) and later answers that same read from the batch's result
/// (replay), so the driver's own ReadSample decodes and judges freshness either way. Every
/// driver reads a sample in exactly one Read transaction.
/// The longest sample read of any driver (ADXL357: STATUS..ZDATA1).
constexpr uint8_t kMaxSampleBytes = 13;

class SampleBus final : public drivers::I2cBus {
 public:
  enum class Mode : uint8_t { kForward, kCapture, kReplay };
  struct Transfer {
    uint8_t addr7, reg, n;
  };

  void set_target(drivers::I2cBus* target) { target_ = target; }
  void Capture() {
    mode_ = Mode::kCapture;
    captured_ = Transfer{0, 0, 0};
  }
  void Replay(drivers::I2cStatus status, const uint8_t* data) {
    mode_ = Mode::kReplay;
    replay_status_ = status;
    replay_ = data;
  }
  void Forward() { mode_ = Mode::kForward; }
  /// The read recorded by the last capture.
  const Transfer& captured() const { return captured_; }

  drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override;
  drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override;

 private:
  drivers::I2cBus* target_ = nullptr;
  Mode mode_ = Mode::kForward;
  Transfer captured_ = {0, 0, 0};
  drivers::I2cStatus replay_status_ = drivers::I2cStatus::kOk;
  const uint8_t* replay_ = nullptr;
};

class Sensor {
 public:
  Sensor() = default;
  Sensor(const Sensor&) = delete;
  Sensor& operator=(const Sensor&) = delete;

  /// (Re)binds the slot to its bus and settings and constructs the driver in place; clears the
  /// fault state. Does not touch the bus (Probe does).
  void Bind(drivers::I2cBus& bus, drivers::Delay& delay, const SensorConfig& cfg,
            const Calibration& cal, uint16_t rate_hz);
  /// Updates only the calibration map (set_calibration).
  void SetCalibration(const SensorConfig& cfg, const Calibration& cal);
  /// Identifies and configures the chip; records the ID register and the fault bits.
  void Probe();
  /// One loop's read: fresh, stale, NACK, saturation and frozen bookkeeping. `periods`: the
  /// sample periods the loop spans (more than 1 when it overran): frozen is a time, not a count
  /// of loops.
  void Sample(uint8_t periods = 1);
  /// Asynchronous sampling, step 1: the one read the next Sample needs (address, register,
  /// length, at most kMaxSampleBytes), without touching the bus. False when Sample would not
  /// read (unbound or not configured): call Sample() as usual then.
  bool PrepareSample(SampleBus::Transfer* t);
  /// Step 2: Sample() with its read answered by `status` and `data` (the batch's result).
  void CompleteSample(drivers::I2cStatus status, const uint8_t* data, uint8_t periods = 1);
  /// Re-reads the identification register of a working sensor (one 1-byte transaction): a part
  /// that starts answering with another ID is flagged wrong_id and taken out until a probe
  /// finds the right part again. A frozen one also has its mode register read (one more byte):
  /// a part that reset itself to standby or CONFIG mode is probed again.
  void CheckId();

  bool bound() const { return kind_ != Kind::kNone; }
  /// Usable by the filter: configured, answering, right ID, not saturated, not frozen.
  bool usable() const {
    return bound() && configured_ && has_value_ && !saturated_ && !map_saturated_ &&
           unchanged_ < frozen_limit_;
  }
  /// PrepareSample would queue a read (bound and configured).
  bool sample_ready() const { return bound() && configured_; }
  /// Needs a new probe (absent, NACKed, wrong ID or failed verification).
  bool needs_probe() const { return needs_probe_; }
  /// status() has kNack.
  bool nacked() const { return bound() && nack_; }
  /// Status bits of this loop (proto::sensor_status). Inline: read several times a loop.
  uint8_t status() const {
    namespace ss = proto::sensor_status;
    if (!bound()) return ss::kNotConfigured;
    uint8_t b = 0;
    if (nack_) b |= ss::kNack;
    if (wrong_id_) b |= ss::kWrongId;
    if (map_saturated_) b |= ss::kBadCalibration;
    if (saturated_) b |= ss::kSaturated;
    if (configured_ && unchanged_ >= frozen_limit_) b |= ss::kFrozen;
    if (fresh_ == 0) b |= ss::kStale;
    if (!configured_ && !nack_ && !wrong_id_) b |= ss::kNotConfigured;
    return b;
  }

  const drivers::RawSample& counts() const { return counts_; }
  const LinkReading& reading() const { return reading_; }
  uint8_t fresh() const { return fresh_; }
  uint8_t chip_id() const { return chip_id_; }
  uint16_t nacks() const { return nacks_; }
  uint16_t id_errors() const { return id_errors_; }
  uint16_t saturations() const { return saturations_; }
  uint16_t freezes() const { return freezes_; }
  uint16_t calibration_saturations() const { return cal_saturations_; }
  /// This loop's calibrated reading saturated Q15.16.
  bool calibration_saturated() const { return cal_saturated_; }

 private:
  enum class Kind : uint8_t { kNone, kAdxl345, kAdxl357, kBno055 };
  static uint16_t Increment(uint16_t v) { return v == 0xFFFF ? v : static_cast<uint16_t>(v + 1); }
  drivers::DeviceStatus Configure();
  drivers::DeviceStatus Read(drivers::RawSample* out);
  /// The part is in its measuring mode (read back; true when the read fails).
  bool StillMeasuring();
  /// Sample's bookkeeping of one read's outcome: faults, freshness, calibration, frozen.
  void Account(drivers::DeviceStatus st, const drivers::RawSample& s, uint8_t periods);
  void DestroyDriver();

  // The fields of every loop first: within 64 bytes of `this`, avr-gcc reaches them with one
  // ldd/std (Y+q); behind the driver storage each access took a pointer computation.
  Kind kind_ = Kind::kNone;
  drivers::RawSample counts_;
  LinkReading reading_ = {0, 0};
  uint8_t chip_id_ = 0;
  uint8_t fresh_ = 0;
  bool configured_ = false;  // a probe succeeded since Bind
  bool needs_probe_ = true;
  bool nack_ = false;
  bool wrong_id_ = false;
  bool saturated_ = false;
  bool has_value_ = false;
  bool cal_saturated_ = false;
  bool map_saturated_ = false;  // map_.saturated, here within reach (usable() every loop)
  uint16_t unchanged_ = 0;      // sample periods without a changed value (saturates)
  uint16_t nacks_ = 0, id_errors_ = 0, saturations_ = 0, freezes_ = 0, cal_saturations_ = 0;
  uint16_t frozen_limit_ = 0;  // unchanged periods before the output counts as frozen
  int32_t saturation_counts_ = 0;
  // In-place storage for whichever driver the slot holds (placement new; never the heap).
  union Storage {
    Storage() {}
    ~Storage() {}
    drivers::Adxl345 adxl345;
    drivers::Adxl357 adxl357;
    drivers::Bno055 bno055;
  } driver_;
  SampleBus sample_bus_;                             // what the driver talks to
  SampleBus::Transfer sample_transfer_ = {0, 0, 0};  // captured once per Bind (PrepareSample)
  drivers::I2cBus* bus_ = nullptr;
  uint8_t address_ = 0;
  uint8_t model_ = 0;
  uint8_t range_g_ = 0;
  uint16_t rate_hz_ = 0;
  CalibrationMap map_ = {};
};

}  // namespace app
}  // namespace ja
