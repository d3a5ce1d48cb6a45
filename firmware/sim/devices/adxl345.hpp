// Virtual ADXL345 (docs/sensors.md §A1; Analog Devices datasheet Rev. E; the devices' README).
// Modelled: DEVID; BW_RATE (ODR = 3200 Hz / 2^(15 - code), LOW_POWER kept); POWER_CTL (MEASURE
// starts conversions, SLEEP samples at the WAKEUP rate 8/4/2/1 Hz, standby holds the data, LINK
// makes activity and inactivity alternate); DATA_FORMAT (range, FULL_RES: 3.9 mg/LSB with 10 +
// range bits, else 10 bits at 3.9 mg * 2^range; JUSTIFY: MSB aligned); OFSX/Y/Z (15.6 mg/LSB,
// added); DATAX0..DATAZ1 little-endian. The LSB reads 0 at 1600/3200 Hz when it is 3.9 mg
// (datasheet p.32). FIFO_CTL modes: bypass (the data registers hold the newest conversion), FIFO
// (collects up to 32 then stops), stream (keeps the newest 32), trigger (keeps the newest 32 until
// an interrupt on the pin the trigger bit selects, then the newest `samples` of them and collects
// as FIFO; FIFO_STATUS FIFO_TRIG until bypass); in those modes the data registers show the oldest
// entry and a transaction that read them pops it at its STOP; FIFO_STATUS entries; bypass clears
// the FIFO. INT_SOURCE: DATA_READY, watermark (entries >= samples; samples 0 sets it at once) and
// overrun always, cleared by the data (bypass: a data read; FIFO modes: the FIFO's level);
// SINGLE_TAP, DOUBLE_TAP, activity, inactivity, FREE_FALL when enabled in INT_ENABLE, evaluated
// on every conversion from THRESH_TAP/DUR/LATENT/WINDOW/TAP_AXES (suppress), THRESH_ACT/
// THRESH_INACT/TIME_INACT/ACT_INACT_CTL (dc and ac coupling), THRESH_FF/TIME_FF, cleared by
// reading INT_SOURCE; ACT_TAP_STATUS axis sources; INT_MAP decides the pin (int1()/int2()).
// Registers latch for the length of a transaction. Not modelled: AUTO_SLEEP and the Asleep bit,
// detection faster than the ODR (tap timing resolves to one conversion period), self-test
// deflection, noise (the motion carries it), the pins on the AVR board.
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
  static constexpr uint8_t kRegThreshTap = 0x1D;
  static constexpr uint8_t kRegOfsX = 0x1E;
  static constexpr uint8_t kRegDur = 0x21;
  static constexpr uint8_t kRegLatent = 0x22;
  static constexpr uint8_t kRegWindow = 0x23;
  static constexpr uint8_t kRegThreshAct = 0x24;
  static constexpr uint8_t kRegThreshInact = 0x25;
  static constexpr uint8_t kRegTimeInact = 0x26;
  static constexpr uint8_t kRegActInactCtl = 0x27;
  static constexpr uint8_t kRegThreshFf = 0x28;
  static constexpr uint8_t kRegTimeFf = 0x29;
  static constexpr uint8_t kRegTapAxes = 0x2A;
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
  static constexpr uint8_t kIntSingleTap = 0x40;
  static constexpr uint8_t kIntDoubleTap = 0x20;
  static constexpr uint8_t kIntActivity = 0x10;
  static constexpr uint8_t kIntInactivity = 0x08;
  static constexpr uint8_t kIntFreeFall = 0x04;
  static constexpr uint8_t kIntWatermark = 0x02;
  static constexpr uint8_t kIntOverrun = 0x01;
  static constexpr uint8_t kPowerMeasure = 0x08;
  static constexpr uint8_t kPowerSleep = 0x04;
  static constexpr uint8_t kPowerLink = 0x20;
  static constexpr uint8_t kFifoBypass = 0x00;
  static constexpr uint8_t kFifoFifo = 0x40;
  static constexpr uint8_t kFifoStream = 0x80;
  static constexpr uint8_t kFifoTrigger = 0xC0;
  static constexpr uint8_t kFifoTrigBit = 0x20;  // FIFO_CTL: trigger on INT2 (else INT1)
  static constexpr uint8_t kFifoStatusTrig = 0x80;
  static constexpr int kFifoLevels = 32;
  static constexpr uint8_t kFormatFullRes = 0x08;
  static constexpr uint8_t kFormatJustify = 0x04;
  static constexpr double kGPerLsb = 0.0039;        // full resolution, every range
  static constexpr double kOffsetGPerLsb = 0.0156;  // OFSx

  explicit Adxl345(uint8_t addr7 = kAddressAltLow, const MotionSource* motion = nullptr);
  const char* model() const override { return "adxl345"; }
  void PowerOnReset() override;
  void set_motion(const MotionSource* motion) { motion_ = motion; }
  /// The part's oscillator (sampling.hpp): used from the next start of conversions and at once
  /// by a running clock (restarted now on its new grid).
  void set_oscillator(const Oscillator& o);
  const Oscillator& oscillator() const { return clock_.oscillator(); }

  /// Conversion period now, as the part's oscillator runs it (0 when not converting).
  uint64_t period_ns() const { return clock_.running() ? clock_.period_ns() : 0; }
  /// The counts (right-justified, sign-extended) held in the data registers.
  int32_t counts(int axis) const { return counts_[axis]; }
  /// Size of one count in m/s^2 for the current DATA_FORMAT.
  double lsb_mps2() const;
  int fifo_entries() const { return fifo_count_; }
  /// The interrupt pins (active high, as INT_INVERT = 0): sources enabled and mapped to them.
  bool int1() const;
  bool int2() const;

 protected:
  uint8_t ReadRegister(uint8_t reg) override;
  bool WriteRegister(uint8_t reg, uint8_t value) override;
  void Update() override;
  void OnStop() override;

 private:
  void Reclock();
  void Convert(uint64_t t_ns);
  void Detect(uint64_t t_ns);
  void DetectTap(uint64_t t_ns, const double g[3]);
  void Store();
  void ClearFifo();
  bool fifo_mode() const { return (regs_[kRegFifoCtl] & 0xC0u) != kFifoBypass; }
  uint8_t IntSource() const;
  bool Pin(bool int2) const;
  uint8_t Bits() const;
  uint16_t Encoded(int axis) const;

  const MotionSource* motion_;
  uint8_t regs_[0x40];
  int32_t counts_[3];  // the data registers
  int32_t sample_[3];  // the newest conversion
  bool data_ready_ = false;
  bool overrun_ = false;
  bool unread_ = false;  // the newest conversion has not been read yet
  SampleClock clock_;
  // The FIFO (modes other than bypass): oldest at fifo_head_; its head is in the data registers.
  int32_t fifo_[kFifoLevels][3];
  int fifo_head_ = 0, fifo_count_ = 0;
  bool fifo_full_event_ = false;  // FIFO modes: overrun, until the FIFO is read
  bool triggered_ = false;        // trigger mode: the event came (FIFO_STATUS FIFO_TRIG)
  bool popped_ = false;           // this transaction read the data registers
  // Event sources (INT_SOURCE bits 6..2), cleared by reading INT_SOURCE.
  uint8_t events_ = 0;
  // Detection state (device time, ns).
  enum class Tap : uint8_t { kIdle, kFirst, kLatency, kWindow, kSecond, kWaitBelow };
  Tap tap_ = Tap::kIdle;
  uint64_t tap_start_ns_ = 0, tap_end_ns_ = 0;
  bool tap_above_ = false;
  uint64_t inact_since_ns_ = 0, ff_since_ns_ = 0;
  bool inact_timing_ = false, ff_timing_ = false;
  bool act_ref_set_ = false, inact_ref_set_ = false;
  double act_ref_g_[3] = {0, 0, 0}, inact_ref_g_[3] = {0, 0, 0};
  bool link_seek_activity_ = false;  // LINK: inactivity was seen, activity is looked for
};

}  // namespace sim
}  // namespace ja
