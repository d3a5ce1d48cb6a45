// Virtual ADXL357 (ADXL355 register map; docs/sensors.md §A2). Modelled: DEVID_AD 0xAD, DEVID_MST
// 0x1D, PARTID 0xED, REVID; STATUS DATA_RDY (cleared when a data register is read); TEMP2/TEMP1
// (1852 LSB at 25 C); XDATA3..ZDATA1: 20-bit two's complement, big-endian, left-justified
// (x = D3 << 12 | D2 << 4 | D1 >> 4); FILTER ODR_LPF (ODR = 4000 Hz / 2^code, codes 0..10);
// RANGE (01 +-10 g 51200 LSB/g, 10 +-20 g, 11 +-40 g); POWER_CTL STANDBY (reset: standby);
// RESET (0x52: power-on values). Range and ODR changes while measuring are applied but counted
// as config violations (the datasheet has them made in standby). Registers latch for the
// length of a transaction. Not modelled: FIFO (FIFO_ENTRIES 0, FIFO_DATA reads 0), offsets,
// activity detection, high-pass filter, self-test, the turn-on settling time.
#pragma once

#include <stdint.h>

#include "sim/devices/i2c_target.hpp"
#include "sim/devices/motion.hpp"
#include "sim/devices/sampling.hpp"

namespace ja {
namespace sim {

class Adxl357 final : public RegisterDevice {
 public:
  static constexpr uint8_t kAddressAselLow = 0x1D;
  static constexpr uint8_t kAddressAselHigh = 0x53;
  static constexpr uint8_t kRegDevIdAd = 0x00;
  static constexpr uint8_t kRegDevIdMst = 0x01;
  static constexpr uint8_t kRegPartId = 0x02;
  static constexpr uint8_t kRegRevId = 0x03;
  static constexpr uint8_t kDevIdAd = 0xAD;
  static constexpr uint8_t kDevIdMst = 0x1D;
  static constexpr uint8_t kPartId = 0xED;
  static constexpr uint8_t kRevId = 0x01;
  static constexpr uint8_t kRegStatus = 0x04;
  static constexpr uint8_t kRegFifoEntries = 0x05;
  static constexpr uint8_t kRegTemp2 = 0x06;
  static constexpr uint8_t kRegTemp1 = 0x07;
  static constexpr uint8_t kRegXData3 = 0x08;
  static constexpr uint8_t kRegFifoData = 0x11;
  static constexpr uint8_t kRegOffsetXH = 0x1E;
  static constexpr uint8_t kRegFilter = 0x28;
  static constexpr uint8_t kRegFifoSamples = 0x29;
  static constexpr uint8_t kRegRange = 0x2C;
  static constexpr uint8_t kRegPowerCtl = 0x2D;
  static constexpr uint8_t kRegSelfTest = 0x2E;
  static constexpr uint8_t kRegReset = 0x2F;
  static constexpr uint8_t kResetCode = 0x52;
  static constexpr uint8_t kStatusDataReady = 0x01;
  static constexpr uint8_t kPowerStandby = 0x01;
  static constexpr uint8_t kRangeReset = 0x81;  // I2C_HS, +-10 g
  static constexpr uint8_t kFifoSamplesReset = 0x60;
  static constexpr uint16_t kTemp25C = 1852;  // LSB at 25 C

  explicit Adxl357(uint8_t addr7 = kAddressAselLow, const MotionSource* motion = nullptr);
  const char* model() const override { return "adxl357"; }
  void PowerOnReset() override;
  void set_motion(const MotionSource* motion) { motion_ = motion; }

  uint64_t period_ns() const { return clock_.running() ? clock_.period_ns() : 0; }
  int32_t counts(int axis) const { return counts_[axis]; }
  /// LSB per g for the current RANGE (reserved code 00 behaves as +-10 g).
  double lsb_per_g() const;

 protected:
  uint8_t ReadRegister(uint8_t reg) override;
  bool WriteRegister(uint8_t reg, uint8_t value) override;
  void Update() override;

 private:
  void Reclock();
  void Convert(uint64_t t_ns);

  const MotionSource* motion_;
  uint8_t regs_[0x30];
  int32_t counts_[3];
  bool data_ready_ = false;
  bool unread_ = false;
  SampleClock clock_;
};

}  // namespace sim
}  // namespace ja
