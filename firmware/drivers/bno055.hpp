// BNO055 in accelerometer-only mode (docs/sensors.md §A3) over an I2cBus: CHIP_ID check,
// CONFIG mode -> page 1 ACC_Config (range, bandwidth) -> page 0 units -> ACCONLY, with the
// datasheet's mode-switch times waited through an injected Delay.
#pragma once

#include <stdint.h>

#include "drivers/conversion.hpp"
#include "drivers/i2c_bus.hpp"

namespace ja {
namespace drivers {
namespace bno055 {
constexpr uint8_t kAddressCom3Low = 0x28;
constexpr uint8_t kAddressCom3High = 0x29;
constexpr uint8_t kRegChipId = 0x00;  // page 0
constexpr uint8_t kChipId = 0xA0;
constexpr uint8_t kRegPageId = 0x07;       // both pages
constexpr uint8_t kRegAccDataXLsb = 0x08;  // page 0: X, Y, Z little-endian int16
constexpr uint8_t kAccDataBytes = 6;       // the sample read's burst from ACC_DATA_X_LSB
constexpr uint8_t kRegUnitSel = 0x3B;      // bit0: 0 = m/s^2 (100 LSB per m/s^2), 1 = mg
constexpr uint8_t kRegOprMode = 0x3D;
constexpr uint8_t kRegAccConfig = 0x08;  // page 1: [1:0] range, [4:2] bandwidth, [7:5] power
constexpr uint8_t kModeConfig = 0x00;
constexpr uint8_t kModeAccOnly = 0x01;
constexpr uint8_t kUnitsMps2 = 0x00;
/// Mode switch times (datasheet table 3-6): CONFIG -> any 7 ms, any -> CONFIG 19 ms; +1 ms.
constexpr uint16_t kToOperatingMs = 8;
constexpr uint16_t kToConfigMs = 20;
constexpr float kMps2PerCount = 0.01f;  // UNIT_SEL accel = m/s^2

enum class Range : uint8_t { k2g = 0, k4g = 1, k8g = 2, k16g = 3 };
enum class Bandwidth : uint8_t {
  k7_81Hz = 0,
  k15_63Hz = 1,
  k31_25Hz = 2,
  k62_5Hz = 3,
  k125Hz = 4,
  k250Hz = 5,
  k500Hz = 6,
  k1000Hz = 7,
};

struct Settings {
  Range range = Range::k4g;
  Bandwidth bandwidth = Bandwidth::k250Hz;
  /// How often the caller reads a sample (Hz; 0 = unknown): at or below the output data rate
  /// every read finds a new conversion (ReadSample).
  uint16_t read_rate_hz = 0;
};
constexpr Settings kDefaultSettings{};

/// Output data rate of the accelerometer for a bandwidth code: twice the bandwidth,
/// 15.625 Hz * 2^code (500 Hz at 250 Hz bandwidth), rounded down.
constexpr uint16_t AccOdrHz(Bandwidth b) {
  return static_cast<uint16_t>((125u << static_cast<uint8_t>(b)) / 8u);
}

/// ACC_Config value: normal power mode (0) in [7:5].
constexpr uint8_t AccConfigValue(const Settings& s) {
  return static_cast<uint8_t>(static_cast<uint8_t>(s.range) |
                              (static_cast<uint8_t>(s.bandwidth) << 2));
}

inline RawSample DecodeSample(const uint8_t* b) {
  RawSample s;
  s.x = static_cast<int16_t>(static_cast<uint16_t>(b[0] | (static_cast<uint16_t>(b[1]) << 8)));
  s.y = static_cast<int16_t>(static_cast<uint16_t>(b[2] | (static_cast<uint16_t>(b[3]) << 8)));
  s.z = static_cast<int16_t>(static_cast<uint16_t>(b[4] | (static_cast<uint16_t>(b[5]) << 8)));
  return s;
}
}  // namespace bno055

class Bno055 {
 public:
  Bno055(I2cBus& bus, Delay& delay, uint8_t addr7) : bus_(bus), delay_(delay), addr7_(addr7) {}

  /// CHIP_ID check, CONFIG mode (wait 20 ms), page 1 ACC_Config with read-back, page 0,
  /// m/s^2 units, ACCONLY (wait 8 ms).
  DeviceStatus Configure(const bno055::Settings& s = bno055::kDefaultSettings);
  /// Reads the 6 acceleration bytes. The BNO055 has no data-ready flag in ACCONLY. When the
  /// caller reads no faster than the output data rate (Settings::read_rate_hz), every read is
  /// a new conversion and fresh, even when it equals the previous one: at 0.01 m/s^2 resolution
  /// a sensor at rest repeats its value often (measured in simulation: 6 % of reads at 100 Hz);
  /// a sensor that stopped converting shows as `frozen` (its value unchanged for seconds). When
  /// it reads faster (or the rate is unknown), an unchanged reading counts as the same
  /// conversion read again: kNotReady.
  DeviceStatus ReadSample(RawSample* out);
  uint16_t fresh_count() const { return fresh_count_; }

 private:
  I2cBus& bus_;
  Delay& delay_;
  uint8_t addr7_;
  uint16_t fresh_count_ = 0;
  RawSample last_;
  bool has_last_ = false;
  bool repeats_are_stale_ = true;  // reads faster than the output data rate (Configure)
};

}  // namespace drivers
}  // namespace ja
