// Virtual BNO055 (docs/sensors.md §A3; Bosch BST-BNO055-DS000; the devices' README). Modelled: page
// 0 IDs (CHIP_ID 0xA0, ACC_ID 0xFB, MAG_ID 0x32, GYR_ID 0x0F), PAGE_ID (pages 0 and 1), OPR_MODE
// with the datasheet's switch times (CONFIG -> any 7 ms, any -> CONFIG 19 ms; during a switch
// writes are dropped and counted, and the new mode's data starts when it completes), SYS_STATUS
// (0 idle in CONFIG, 5 fusion, 6 no fusion), UNIT_SEL (accel m/s^2 = 100 LSB per m/s^2 or mg;
// gyro 16 LSB/dps or 900 LSB/rps; Euler 16 LSB/degree or 900 LSB/rad; Windows or Android pitch),
// AXIS_MAP_CONFIG/SIGN, page 1 ACC_Config (range 2/4/8/16 g, bandwidth; writable only in CONFIG
// mode) and GYR_Config_0 (range, bandwidth). Non-fusion modes convert the accelerometer at ODR =
// 2 x bandwidth and the gyro at its bandwidth's ODR; fusion modes (IMU..NDOF) at 100 Hz with 4 g
// / 2000 dps. Fusion (bno055_fusion.hpp), at 100 Hz from the motion's truth: EUL, QUA, GRV, LIA
// in the fusion modes (IMU and M4G relative to the heading at the mode's start; COMPASS,
// NDOF_FMC_OFF, NDOF absolute), MAG_DATA (16 LSB/uT) from a configurable Earth field in every
// mode with the magnetometer (20 Hz), CALIB_STAT; SYS_TRIGGER keeps CLK_SEL. SYS_TRIGGER RST_SYS
// and power cycles reset the registers and NACK the address for 650 ms while it boots.
// Clock stretching is the bus's: the AVR board's --clock-stretch.
#pragma once

#include <stdint.h>

#include "sim/devices/bno055_fusion.hpp"
#include "sim/devices/i2c_target.hpp"
#include "sim/devices/motion.hpp"
#include "sim/devices/sampling.hpp"

namespace ja {
namespace sim {

class Bno055 final : public RegisterDevice {
 public:
  static constexpr uint8_t kAddressCom3Low = 0x28;
  static constexpr uint8_t kAddressCom3High = 0x29;
  static constexpr uint8_t kRegChipId = 0x00;
  static constexpr uint8_t kChipId = 0xA0;
  static constexpr uint8_t kAccId = 0xFB;
  static constexpr uint8_t kMagId = 0x32;
  static constexpr uint8_t kGyrId = 0x0F;
  static constexpr uint8_t kRegPageId = 0x07;
  static constexpr uint8_t kRegAccData = 0x08;  // page 0, X/Y/Z little-endian int16
  static constexpr uint8_t kRegMagData = 0x0E;
  static constexpr uint8_t kRegGyrData = 0x14;
  static constexpr uint8_t kRegEulData = 0x1A;  // heading, roll, pitch
  static constexpr uint8_t kRegQuaData = 0x20;  // w, x, y, z
  static constexpr uint8_t kRegLiaData = 0x28;
  static constexpr uint8_t kRegGrvData = 0x2E;
  static constexpr uint8_t kRegCalibStat = 0x35;
  static constexpr uint8_t kRegSysClkStatus = 0x38;
  static constexpr uint8_t kRegTemp = 0x34;
  static constexpr uint8_t kRegStResult = 0x36;
  static constexpr uint8_t kRegSysStatus = 0x39;
  static constexpr uint8_t kRegUnitSel = 0x3B;
  static constexpr uint8_t kRegOprMode = 0x3D;
  static constexpr uint8_t kRegPwrMode = 0x3E;
  static constexpr uint8_t kRegSysTrigger = 0x3F;
  static constexpr uint8_t kRegAxisMapConfig = 0x41;
  static constexpr uint8_t kRegAxisMapSign = 0x42;
  static constexpr uint8_t kRegAccConfig = 0x08;  // page 1
  static constexpr uint8_t kRegMagConfig = 0x09;
  static constexpr uint8_t kRegGyrConfig0 = 0x0A;
  static constexpr uint8_t kRegGyrConfig1 = 0x0B;
  static constexpr uint8_t kModeConfig = 0x00;
  static constexpr uint8_t kModeAccOnly = 0x01;
  static constexpr uint8_t kModeAmg = 0x07;
  static constexpr uint8_t kModeImu = 0x08;
  static constexpr uint8_t kModeCompass = 0x09;
  static constexpr uint8_t kModeM4g = 0x0A;
  static constexpr uint8_t kModeNdofFmcOff = 0x0B;
  static constexpr uint8_t kModeNdof = 0x0C;
  static constexpr uint8_t kUnitSelReset = 0x80;
  static constexpr uint8_t kAccConfigReset = 0x0D;  // 4 g, 62.5 Hz, normal
  static constexpr uint8_t kMagConfigReset = 0x6D;
  static constexpr uint8_t kGyrConfig0Reset = 0x38;  // 2000 dps, 32 Hz
  static constexpr uint8_t kAxisMapConfigReset = 0x24;
  static constexpr uint8_t kRstSys = 0x20;
  static constexpr uint8_t kClkSel = 0x80;
  static constexpr uint64_t kToConfigNs = 19000000;   // any -> CONFIG
  static constexpr uint64_t kFromConfigNs = 7000000;  // CONFIG -> any
  static constexpr uint64_t kBootNs = 650000000;      // reset -> CONFIG mode

  explicit Bno055(uint8_t addr7 = kAddressCom3Low, const MotionSource* motion = nullptr);
  const char* model() const override { return "bno055"; }
  /// Power cycle: registers to power-up values; the part boots for kBootNs (NACKs).
  void PowerOnReset() override;
  void set_motion(const MotionSource* motion) { motion_ = motion; }
  /// The part's one oscillator, for the accelerometer's, the gyroscope's and the fusion's clocks
  /// (sampling.hpp): used from their next start and at once by the running ones (restarted now).
  void set_oscillator(const Oscillator& o);
  const Oscillator& oscillator() const { return fusion_clock_.oscillator(); }

  /// The operating mode in effect (OPR_MODE reads the requested one during a switch).
  uint8_t active_mode() const { return mode_; }
  bool switching() const { return switching_; }
  bool booting() const { return now_ns() < boot_done_ns_; }
  /// Periods as the part's oscillator runs them (0 when not converting).
  uint64_t accel_period_ns() const { return acc_clock_.running() ? acc_clock_.period_ns() : 0; }
  uint64_t gyro_period_ns() const { return gyr_clock_.running() ? gyr_clock_.period_ns() : 0; }
  uint64_t fusion_period_ns() const {
    return fusion_clock_.running() ? fusion_clock_.period_ns() : 0;
  }
  int32_t accel_counts(int axis) const { return acc_[axis]; }
  int32_t gyro_counts(int axis) const { return gyr_[axis]; }
  /// The fusion (its truth orientation, Earth field and initial heading).
  Bno055Fusion& fusion() { return fusion_; }
  const Bno055Fusion& fusion() const { return fusion_; }

 protected:
  bool AcceptAddress(bool read) override;
  uint8_t ReadRegister(uint8_t reg) override;
  bool WriteRegister(uint8_t reg, uint8_t value) override;
  void Update() override;

 private:
  void ResetRegisters();
  void Reclock(uint64_t at_ns);
  void SettleSwitch();
  void ConvertAccel(uint64_t t_ns);
  void ConvertGyro(uint64_t t_ns);
  void StepFusion(uint64_t t_ns);
  uint8_t CalibStat() const;
  void Remap(const double in[3], double out[3]) const;
  uint8_t WrongId(uint8_t id) const;

  const MotionSource* motion_;
  uint8_t page0_[0x80];
  uint8_t page1_[0x80];
  uint8_t page_ = 0;
  uint8_t mode_ = kModeConfig;  // in effect
  bool switching_ = false;
  uint8_t target_mode_ = kModeConfig;
  uint64_t switch_done_ns_ = 0;
  uint64_t boot_done_ns_ = 0;
  int32_t acc_[3];
  int32_t gyr_[3];
  bool acc_unread_ = false;
  SampleClock acc_clock_;
  SampleClock gyr_clock_;
  // Fusion at 100 Hz (every mode: the magnetometer needs the orientation too).
  Bno055Fusion fusion_;
  SampleClock fusion_clock_;
  uint64_t fusion_steps_ = 0;
  bool heading0_set_ = false;  // relative modes: the heading at the mode's start is taken
  double heading0_deg_ = 0.0;
  int16_t mag_[3], eul_[3], qua_[4], lia_[3], grv_[3];
  uint8_t sys_trigger_ = 0;  // CLK_SEL as written
};

}  // namespace sim
}  // namespace ja
