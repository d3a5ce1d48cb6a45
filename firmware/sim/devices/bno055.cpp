#include "sim/devices/bno055.hpp"

#include <string.h>

#include <cmath>

namespace ja {
namespace sim {

namespace {
constexpr double kPi = 3.14159265358979323846;

bool HasAccel(uint8_t mode) {
  return mode == 0x01 || mode == 0x04 || mode == 0x05 || mode == 0x07 || mode >= 0x08;
}
bool HasGyro(uint8_t mode) {
  return mode == 0x03 || mode == 0x05 || mode == 0x06 || mode == 0x07 || mode == 0x08 ||
         mode == 0x0B || mode == 0x0C;
}
bool IsFusion(uint8_t mode) { return mode >= 0x08; }
bool HasMag(uint8_t mode) {
  return mode == 0x02 || mode == 0x04 || mode == 0x06 || mode == 0x07 || mode >= 0x09;
}
bool IsAbsolute(uint8_t mode) { return mode == 0x09 || mode == 0x0B || mode == 0x0C; }
int16_t Clamp16(double counts) {
  if (!(counts == counts)) return 0;
  const double c = std::round(counts);
  return static_cast<int16_t>(c > 32767 ? 32767 : c < -32768 ? -32768 : c);
}
// Gyro ODR per GYR_Config_0 bandwidth code (BMG160: 523/230 Hz at 2 kHz, 116 Hz at 1 kHz, ...).
constexpr uint64_t kGyroPeriodNs[8] = {500000,  500000,   1000000, 2500000,
                                       5000000, 10000000, 5000000, 10000000};
}  // namespace

Bno055::Bno055(uint8_t addr7, const MotionSource* motion) : RegisterDevice(addr7), motion_(motion) {
  ResetRegisters();  // created powered up and booted
}

void Bno055::ResetRegisters() {
  memset(page0_, 0, sizeof page0_);
  memset(page1_, 0, sizeof page1_);
  page0_[0x00] = kChipId;
  page0_[0x01] = kAccId;
  page0_[0x02] = kMagId;
  page0_[0x03] = kGyrId;
  page0_[0x04] = 0x11;  // SW_REV 0x0311
  page0_[0x05] = 0x03;
  page0_[0x06] = 0x15;  // BL_REV
  page0_[kRegUnitSel] = kUnitSelReset;
  page0_[kRegAxisMapConfig] = kAxisMapConfigReset;
  page1_[kRegAccConfig] = kAccConfigReset;
  page1_[kRegMagConfig] = kMagConfigReset;
  page1_[kRegGyrConfig0] = kGyrConfig0Reset;
  page_ = 0;
  mode_ = target_mode_ = kModeConfig;
  switching_ = false;
  acc_[0] = acc_[1] = acc_[2] = 0;
  gyr_[0] = gyr_[1] = gyr_[2] = 0;
  acc_unread_ = false;
  acc_clock_.Stop();
  gyr_clock_.Stop();
  fusion_.Reset();
  fusion_clock_.Start(now_ns(), Bno055Fusion::kStepNs);
  fusion_steps_ = 0;
  heading0_set_ = false;
  memset(mag_, 0, sizeof mag_);
  memset(eul_, 0, sizeof eul_);
  memset(qua_, 0, sizeof qua_);
  memset(lia_, 0, sizeof lia_);
  memset(grv_, 0, sizeof grv_);
  sys_trigger_ = 0;
}

void Bno055::PowerOnReset() {
  ResetRegisters();
  boot_done_ns_ = now_ns() + kBootNs;
}

bool Bno055::AcceptAddress(bool /*read*/) { return !booting(); }

void Bno055::set_oscillator(const Oscillator& o) {
  SampleClock* const clocks[3] = {&acc_clock_, &gyr_clock_, &fusion_clock_};
  for (SampleClock* c : clocks) {
    c->set_oscillator(o);
    c->Restart(now_ns());
  }
}

void Bno055::Reclock(uint64_t at_ns) {
  if (HasAccel(mode_)) {
    const uint64_t p =
        IsFusion(mode_) ? 10000000u : (64000000ull >> ((page1_[kRegAccConfig] >> 2) & 7u));
    acc_clock_.Start(at_ns, p);
  } else {
    acc_clock_.Stop();
  }
  if (HasGyro(mode_)) {
    const uint64_t p =
        IsFusion(mode_) ? 10000000u : kGyroPeriodNs[(page1_[kRegGyrConfig0] >> 3) & 7u];
    gyr_clock_.Start(at_ns, p);
  } else {
    gyr_clock_.Stop();
  }
}

void Bno055::SettleSwitch() {
  if (switching_ && now_ns() >= switch_done_ns_) {
    switching_ = false;
    mode_ = target_mode_;
    Reclock(switch_done_ns_);
    heading0_set_ = false;  // a relative mode counts heading from its start
    if (!IsFusion(mode_)) {
      memset(eul_, 0, sizeof eul_);
      memset(qua_, 0, sizeof qua_);
      memset(lia_, 0, sizeof lia_);
      memset(grv_, 0, sizeof grv_);
    }
    if (!HasMag(mode_)) memset(mag_, 0, sizeof mag_);
  }
}

void Bno055::Update() {
  SettleSwitch();
  if (conversions_stopped()) return;
  uint64_t t_ns = 0;
  uint64_t n = acc_clock_.Advance(now_ns(), &t_ns);
  if (n) {
    CountConversions(n, &acc_unread_);
    if (!fault(FaultKind::kFrozen)) ConvertAccel(t_ns);
  }
  n = gyr_clock_.Advance(now_ns(), &t_ns);
  if (n && !fault(FaultKind::kFrozen)) ConvertGyro(t_ns);
  // The fusion steps due, in order (a longer jump keeps the newest 4096: 41 s).
  n = fusion_clock_.Advance(now_ns(), &t_ns);
  const uint64_t replay = n < 4096 ? n : 4096;
  if (n > replay) fusion_.Realign();  // lost track: aligned again from the next sample
  for (uint64_t i = replay; i-- > 0;) StepFusion(t_ns - i * fusion_clock_.period_ns());
}

void Bno055::StepFusion(uint64_t t_ns) {
  if (!motion_) return;  // the orientation is tracked from power-up, booting included
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (!motion_->Sample(t_ns, &m)) return;
  double a[3], w[3];
  Remap(m.accel_mps2, a);
  Remap(m.gyro_rps, w);
  const bool fusing = IsFusion(mode_) && !switching_;
  uint8_t calibrate = 0;
  if (fusing)
    calibrate = static_cast<uint8_t>(1u | (HasGyro(mode_) ? 2u : 0u) | (HasMag(mode_) ? 4u : 0u));
  fusion_.Step(t_ns, a, w, m.has_gyro, calibrate);
  ++fusion_steps_;
  if (fault(FaultKind::kFrozen) || !fusion_.initialised()) return;  // outputs hold
  if (HasMag(mode_) && !switching_ && fusion_steps_ % 5 == 0) {     // 20 Hz
    double b[3];
    fusion_.Magnetometer(b);
    for (int k = 0; k < 3; ++k) mag_[k] = Clamp16(b[k] * 16.0);
  }
  if (!fusing) return;
  const bool absolute = IsAbsolute(mode_);
  if (!heading0_set_) {
    double h, r, p;
    EulerFromQuaternion(fusion_.orientation(), &h, &r, &p);
    heading0_deg_ = h;
    heading0_set_ = true;
  }
  const Quaternion q = fusion_.Reported(t_ns, absolute, heading0_deg_);
  double heading, roll, pitch;
  EulerFromQuaternion(q, &heading, &roll, &pitch);
  const uint8_t units = page0_[kRegUnitSel];
  if (units & 0x80u) pitch = -pitch;  // Android orientation
  const double per_deg = (units & 0x04u) ? 900.0 * kPi / 180.0 : 16.0;
  eul_[0] = Clamp16(heading * per_deg);
  eul_[1] = Clamp16(roll * per_deg);
  eul_[2] = Clamp16(pitch * per_deg);
  const double qv[4] = {q.w, q.x, q.y, q.z};
  for (int k = 0; k < 4; ++k) qua_[k] = Clamp16(qv[k] * 16384.0);
  const double up[3] = {0, 0, kStandardGravity};
  double g[3];
  RotateToSensor(q, up, g);
  const double per_mps2 = (units & 0x01u) ? 1000.0 / kStandardGravity : 100.0;
  for (int k = 0; k < 3; ++k) {
    grv_[k] = Clamp16(g[k] * per_mps2);
    lia_[k] = Clamp16((a[k] - g[k]) * per_mps2);
  }
}

uint8_t Bno055::CalibStat() const {
  const bool fast = mode_ != kModeNdofFmcOff;
  const uint8_t acc = fusion_.acc_level(), gyr = fusion_.gyr_level();
  const uint8_t mag = fusion_.mag_level(fast);
  // SYS: what the running fusion mode rests on (gyroscope for IMU, magnetometer for the compass
  // modes, both for NDOF); 0 outside fusion.
  uint8_t sys = 0;
  if (mode_ == kModeImu) {
    sys = gyr;
  } else if (mode_ == kModeCompass || mode_ == kModeM4g) {
    sys = mag;
  } else if (mode_ == kModeNdofFmcOff || mode_ == kModeNdof) {
    sys = gyr < mag ? gyr : mag;
  }
  return static_cast<uint8_t>(sys << 6 | gyr << 4 | acc << 2 | mag);
}

void Bno055::Remap(const double in[3], double out[3]) const {
  const uint8_t map = page0_[kRegAxisMapConfig];
  const uint8_t sign = page0_[kRegAxisMapSign];
  for (int k = 0; k < 3; ++k) {
    uint8_t src = static_cast<uint8_t>((map >> (2 * k)) & 3u);
    if (src > 2) src = static_cast<uint8_t>(k);  // invalid code: identity
    const bool neg = (sign >> (2 - k)) & 1u;
    out[k] = neg ? -in[src] : in[src];
  }
}

void Bno055::ConvertAccel(uint64_t t_ns) {
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (motion_) motion_->Sample(t_ns, &m);
  double a[3];
  Remap(m.accel_mps2, a);
  const bool mg = page0_[kRegUnitSel] & 0x01u;
  const uint8_t range_code = IsFusion(mode_) ? 1u : (page1_[kRegAccConfig] & 3u);
  const double range_mps2 = static_cast<double>(2u << range_code) * kStandardGravity;
  const double lsb = mg ? kStandardGravity / 1000.0 : 0.01;
  const int32_t hi = static_cast<int32_t>(range_mps2 / lsb + 0.5);
  const uint8_t mask = static_cast<uint8_t>(fault_param(FaultKind::kSaturate) & 7u);
  for (int k = 0; k < 3; ++k) {
    int32_t c = ToCounts(a[k], lsb, -hi, hi);
    if (fault(FaultKind::kSaturate) && (mask == 0 || (mask >> k) & 1u)) c = Rail(a[k], -hi, hi);
    acc_[k] = c;
  }
}

void Bno055::ConvertGyro(uint64_t t_ns) {
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (motion_) motion_->Sample(t_ns, &m);
  double w[3];
  Remap(m.gyro_rps, w);
  const bool rps = page0_[kRegUnitSel] & 0x02u;
  uint8_t range_code = IsFusion(mode_) ? 0u : (page1_[kRegGyrConfig0] & 7u);
  if (range_code > 4) range_code = 4;
  const double range_dps = 2000.0 / static_cast<double>(1u << range_code);
  const double lsb_rps = rps ? 1.0 / 900.0 : (kPi / 180.0) / 16.0;
  const int32_t hi = static_cast<int32_t>(range_dps * (kPi / 180.0) / lsb_rps + 0.5);
  for (int k = 0; k < 3; ++k) gyr_[k] = ToCounts(w[k], lsb_rps, -hi, hi);
}

uint8_t Bno055::WrongId(uint8_t id) const {
  const uint32_t p = fault_param(FaultKind::kWrongId);
  return static_cast<uint8_t>(p ? p : static_cast<uint8_t>(~id));
}

uint8_t Bno055::ReadRegister(uint8_t reg) {
  if (reg == kRegPageId) return page_;
  if (reg >= 0x80) return 0;
  if (page_ == 1) return page1_[reg];
  if (reg == kRegChipId && fault(FaultKind::kWrongId)) return WrongId(kChipId);
  if (reg >= kRegAccData && reg < kRegAccData + 6) {
    const int i = reg - kRegAccData;
    if (acc_unread_) ++counters_.samples_read;
    acc_unread_ = false;
    const uint16_t v = static_cast<uint16_t>(acc_[i / 2]);
    return static_cast<uint8_t>((i & 1) ? v >> 8 : v & 0xFFu);
  }
  if (reg >= kRegGyrData && reg < kRegGyrData + 6) {
    const int i = reg - kRegGyrData;
    const uint16_t v = static_cast<uint16_t>(gyr_[i / 2]);
    return static_cast<uint8_t>((i & 1) ? v >> 8 : v & 0xFFu);
  }
  const auto le = [](const int16_t* v, int i) {
    const uint16_t u = static_cast<uint16_t>(v[i / 2]);
    return static_cast<uint8_t>((i & 1) ? u >> 8 : u & 0xFFu);
  };
  if (reg >= kRegMagData && reg < kRegMagData + 6) return le(mag_, reg - kRegMagData);
  if (reg >= kRegEulData && reg < kRegEulData + 6) return le(eul_, reg - kRegEulData);
  if (reg >= kRegQuaData && reg < kRegQuaData + 8) return le(qua_, reg - kRegQuaData);
  if (reg >= kRegLiaData && reg < kRegLiaData + 6) return le(lia_, reg - kRegLiaData);
  if (reg >= kRegGrvData && reg < kRegGrvData + 6) return le(grv_, reg - kRegGrvData);
  if (reg == kRegCalibStat) return CalibStat();
  if (reg == kRegSysClkStatus) return 0;  // free to configure the clock
  if (reg == kRegTemp) return 25;         // C (UNIT_SEL bit4 = 0)
  if (reg == kRegStResult) return 0x0F;   // every self test passed
  if (reg == kRegSysStatus) return mode_ == kModeConfig ? 0 : IsFusion(mode_) ? 5 : 6;
  if (reg == kRegSysTrigger) return sys_trigger_;  // CLK_SEL; the action bits read 0
  return page0_[reg];
}

bool Bno055::WriteRegister(uint8_t reg, uint8_t value) {
  if (reg == kRegPageId) {
    page_ = value & 1u;
    return true;
  }
  SettleSwitch();  // a switch may complete while the part is addressed
  if (switching_) {
    ++counters_.writes_ignored;  // the part is busy changing mode
    return true;
  }
  if (reg >= 0x80) {
    ++counters_.writes_ignored;
    return true;
  }
  if (page_ == 1) {
    if (reg >= kRegAccConfig && reg <= kRegGyrConfig1 && mode_ == kModeConfig) {
      page1_[reg] = value;
    } else {
      ++counters_.writes_ignored;  // sensor configuration: CONFIG mode only
    }
    return true;
  }
  if (reg == kRegOprMode) {
    const uint8_t target = value & 0x0Fu;
    page0_[kRegOprMode] = target;
    if (target == mode_) return true;
    if (mode_ != kModeConfig && target != kModeConfig) ++counters_.config_violations;
    switching_ = true;
    target_mode_ = target;
    switch_done_ns_ = now_ns() + (target == kModeConfig ? kToConfigNs : kFromConfigNs);
    acc_clock_.Stop();  // no new data until the new mode runs
    gyr_clock_.Stop();
    return true;
  }
  if (reg == kRegSysTrigger) {
    if (value & kRstSys) {
      PowerOnReset();
    } else {
      sys_trigger_ = value & kClkSel;  // RST_INT and SELF_TEST act and read back 0
    }
    return true;
  }
  const bool writable = reg == kRegUnitSel || reg == kRegPwrMode || reg == 0x40 ||
                        reg == kRegAxisMapConfig || reg == kRegAxisMapSign ||
                        (reg >= 0x55 && reg <= 0x6A);
  if (!writable) {
    ++counters_.writes_ignored;
    return true;
  }
  if (mode_ != kModeConfig && reg != kRegUnitSel) {
    ++counters_.writes_ignored;
    return true;
  }
  page0_[reg] = value;
  if (reg == kRegAxisMapConfig || reg == kRegAxisMapSign) fusion_.Realign();  // a new frame
  return true;
}

}  // namespace sim
}  // namespace ja
