// Virtual ADXL345 (docs/sensors.md §A1; Analog Devices datasheet Rev. E). Modelled: DEVID; BW_RATE
// (ODR = 3200 Hz / 2^(15 - code), LOW_POWER kept); POWER_CTL (MEASURE starts conversions,
// SLEEP samples at the WAKEUP rate 8/4/2/1 Hz, standby holds the data); DATA_FORMAT (range,
// FULL_RES: 3.9 mg/LSB with 10 + range bits, else 10 bits at 3.9 mg * 2^range; JUSTIFY: MSB
// aligned); OFSX/Y/Z (15.6 mg/LSB, added); INT_SOURCE DATA_READY / WATERMARK / OVERRUN in FIFO
// bypass (DATA_READY and OVERRUN clear when a data register is read); DATAX0..DATAZ1 little-
// endian. The LSB reads 0 at 1600/3200 Hz when it is 3.9 mg (datasheet p.32). Registers latch
// for the length of a transaction. Not modelled: FIFO modes (FIFO_STATUS reads 0 entries),
// tap/activity/free-fall detection, self-test deflection, noise (the motion carries it).
#pragma once

#include <stdint.h>

#include "sim/devices/i2c_target.hpp"
#include "sim/devices/motion.hpp"
#include "sim/devices/sampling.hpp"

namespace ja {
namespace sim {

class Adxl345 final : public RegisterDevice {
 public:
  static constexpr uint8_t kAddressAltLow = 0x53;
  static constexpr uint8_t kAddressAltHigh = 0x1D;
  static constexpr uint8_t kRegDevId = 0x00;
  static constexpr uint8_t kDevId = 0xE5;
  static constexpr uint8_t kRegOfsX = 0x1E;
  static constexpr uint8_t kRegActTapStatus = 0x2B;
  static constexpr uint8_t kRegBwRate = 0x2C;
  static constexpr uint8_t kRegPowerCtl = 0x2D;
  static constexpr uint8_t kRegIntEnable = 0x2E;
  static constexpr uint8_t kRegIntMap = 0x2F;
  static constexpr uint8_t kRegIntSource = 0x30;
  static constexpr uint8_t kRegDataFormat = 0x31;
  static constexpr uint8_t kRegDataX0 = 0x32;
  static constexpr uint8_t kRegFifoCtl = 0x38;
  static constexpr uint8_t kRegFifoStatus = 0x39;
  static constexpr uint8_t kBwRateReset = 0x0A;  // 100 Hz
  static constexpr uint8_t kIntSourceReset = 0x02;
  static constexpr uint8_t kIntDataReady = 0x80;
  static constexpr uint8_t kIntWatermark = 0x02;
  static constexpr uint8_t kIntOverrun = 0x01;
  static constexpr uint8_t kPowerMeasure = 0x08;
  static constexpr uint8_t kPowerSleep = 0x04;
  static constexpr uint8_t kFormatFullRes = 0x08;
  static constexpr uint8_t kFormatJustify = 0x04;
  static constexpr double kGPerLsb = 0.0039;        // full resolution, every range
  static constexpr double kOffsetGPerLsb = 0.0156;  // OFSx

  explicit Adxl345(uint8_t addr7 = kAddressAltLow, const MotionSource* motion = nullptr);
  const char* model() const override { return "adxl345"; }
  void PowerOnReset() override;
  void set_motion(const MotionSource* motion) { motion_ = motion; }

  /// Conversion period now (0 when not converting).
  uint64_t period_ns() const { return clock_.running() ? clock_.period_ns() : 0; }
  /// The counts (right-justified, sign-extended) held in the data registers.
  int32_t counts(int axis) const { return counts_[axis]; }
  /// Size of one count in m/s^2 for the current DATA_FORMAT.
  double lsb_mps2() const;

 protected:
  uint8_t ReadRegister(uint8_t reg) override;
  bool WriteRegister(uint8_t reg, uint8_t value) override;
  void Update() override;

 private:
  void Reclock();
  void Convert(uint64_t t_ns);
  uint8_t Bits() const;
  uint16_t Encoded(int axis) const;

  const MotionSource* motion_;
  uint8_t regs_[0x40];
  int32_t counts_[3];
  bool data_ready_ = false;
  bool overrun_ = false;
  bool unread_ = false;  // the newest conversion has not been read yet
  SampleClock clock_;
};

}  // namespace sim
}  // namespace ja
