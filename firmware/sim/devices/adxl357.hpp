// Virtual ADXL357 (ADXL355 register map; docs/sensors.md §A2; the devices' README). Modelled:
// DEVID_AD 0xAD, DEVID_MST 0x1D, PARTID 0xED, REVID; STATUS DATA_RDY (cleared when a data register
// is read), FIFO_FULL (FIFO_ENTRIES >= FIFO_SAMPLES), FIFO_OVR (latched, cleared when STATUS is
// read); TEMP2/TEMP1 (1852 LSB at 25 C); XDATA3..ZDATA1: 20-bit two's complement, big-endian,
// left-justified (x = D3 << 12 | D2 << 4 | D1 >> 4); the 96-entry FIFO (one entry per axis, x y z
// per conversion; FIFO_DATA pops 3 bytes an entry without moving the pointer, marker bit 0 on x,
// empty bit 1 when nothing is left; an entry's bytes may come in separate reads; reached by
// auto-increment FIFO_DATA reads 0 and moves on; on
// overrun the oldest entry is dropped; cleared in standby); OFFSET_X/Y/Z (XDATA[19:4] units, added
// last); activity (ACT_EN axes, |XDATA[18:3]| above ACT_THRESH for ACT_COUNT conversions in a
// row: STATUS bit 3, latched until STATUS is read); FILTER ODR_LPF (ODR = 4000 Hz / 2^code, codes
// 0..10) and HPF_CORNER (first order, corner 24.7e-4 ... 0.0238e-4 x ODR, on the XDATA and FIFO
// outputs; may change while measuring); RANGE (01 +-10 g 51200 LSB/g, 10 +-20 g, 11 +-40 g);
// POWER_CTL STANDBY (reset: standby); RESET (0x52: power-on values). Range and ODR changes while
// measuring are applied but counted as config violations (the datasheet has them made in standby).
// Registers latch for the length of a transaction. Not modelled: INT1/INT2/DRDY pins, SYNC,
// self-test, the low-pass filter's response and group delay, the turn-on settling time.
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
  static constexpr uint8_t kRegActEn = 0x24;
  static constexpr uint8_t kRegActThreshH = 0x25;
  static constexpr uint8_t kRegActCount = 0x27;
  static constexpr uint8_t kRegFilter = 0x28;
  static constexpr uint8_t kRegFifoSamples = 0x29;
  static constexpr uint8_t kRegRange = 0x2C;
  static constexpr uint8_t kRegPowerCtl = 0x2D;
  static constexpr uint8_t kRegSelfTest = 0x2E;
  static constexpr uint8_t kRegReset = 0x2F;
  static constexpr uint8_t kResetCode = 0x52;
  static constexpr uint8_t kRegOffsetZL = 0x23;
  static constexpr uint8_t kStatusDataReady = 0x01;
  static constexpr uint8_t kStatusFifoFull = 0x02;
  static constexpr uint8_t kStatusFifoOverrun = 0x04;
  static constexpr uint8_t kStatusActivity = 0x08;
  static constexpr int kFifoEntries = 96;  // 32 x-y-z sets
  static constexpr uint8_t kFifoMarkerX = 0x01;
  static constexpr uint8_t kFifoEmpty = 0x02;
  static constexpr uint8_t kPowerStandby = 0x01;
  static constexpr uint8_t kRangeReset = 0x81;  // I2C_HS, +-10 g
  static constexpr uint8_t kFifoSamplesReset = 0x60;
  static constexpr uint16_t kTemp25C = 1852;  // LSB at 25 C

  explicit Adxl357(uint8_t addr7 = kAddressAselLow, const MotionSource* motion = nullptr);
  const char* model() const override { return "adxl357"; }
  void PowerOnReset() override;
  void set_motion(const MotionSource* motion) { motion_ = motion; }
  /// The part's oscillator (sampling.hpp): used from the next start of conversions and at once
  /// by a running clock (restarted now on its new grid).
  void set_oscillator(const Oscillator& o);
  const Oscillator& oscillator() const { return clock_.oscillator(); }

  uint64_t period_ns() const { return clock_.running() ? clock_.period_ns() : 0; }
  int32_t counts(int axis) const { return counts_[axis]; }
  int fifo_entries() const { return fifo_count_; }
  /// The high-pass corner in Hz for the current FILTER (0: off).
  double hpf_corner_hz() const;
  /// LSB per g for the current RANGE (reserved code 00 behaves as +-10 g).
  double lsb_per_g() const;

 protected:
  uint8_t ReadRegister(uint8_t reg) override;
  bool WriteRegister(uint8_t reg, uint8_t value) override;
  bool HoldsPointer(uint8_t reg) const override;
  void Update() override;

 private:
  void Reclock();
  void Convert(uint64_t t_ns);
  void PushFifo();
  void DetectActivity();
  void ClearFifo();
  uint8_t FifoByte();

  const MotionSource* motion_;
  uint8_t regs_[0x30];
  int32_t counts_[3];
  bool data_ready_ = false;
  bool unread_ = false;
  bool fifo_overrun_ = false;
  bool activity_ = false;  // STATUS Activity, latched
  uint32_t act_run_ = 0;   // conversions in a row above ACT_THRESH
  SampleClock clock_;
  // The FIFO: entries as 20-bit counts, the axis of the oldest in fifo_axis_ (x y z repeat).
  int32_t fifo_[kFifoEntries];
  int fifo_head_ = 0, fifo_count_ = 0;
  uint8_t fifo_axis_ = 0;
  uint8_t fifo_word_[3] = {0, 0, 0};  // the entry being read out
  uint8_t fifo_byte_ = 0;             // next byte of fifo_word_ (0: pop a new entry)
  // High-pass filter state per axis (m/s^2): last input and output; primed at the first sample.
  double hpf_x_[3] = {0, 0, 0}, hpf_y_[3] = {0, 0, 0};
};

}  // namespace sim
}  // namespace ja
