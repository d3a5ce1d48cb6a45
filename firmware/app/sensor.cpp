#include "app/sensor.hpp"

#include <math.h>

#include <new>

#include "core/numeric_policy.hpp"
#include "protocol/messages.hpp"

namespace ja {
namespace app {

namespace {

constexpr float kTwo30 = 1073741824.0f;
constexpr float kTwo16 = 65536.0f;
constexpr float kFrozenSeconds = 0.2f;  // an output unchanged this long is frozen
constexpr uint16_t kMinFrozenPeriods = 5;

int32_t RoundToRaw(float v, float scale, bool* saturated) {
  const float x = v * scale;
  if (!(x < 2147483520.0f && x > -2147483520.0f)) {
    *saturated = true;
    return x < 0.0f ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
  }
  return static_cast<int32_t>(floorf(x + 0.5f));
}

drivers::adxl345::Settings Adxl345Settings(uint8_t range_g, uint16_t rate_hz) {
  drivers::adxl345::Settings s;
  s.range = range_g >= 16  ? drivers::adxl345::Range::k16g
            : range_g >= 8 ? drivers::adxl345::Range::k8g
            : range_g >= 4 ? drivers::adxl345::Range::k4g
                           : drivers::adxl345::Range::k2g;
  // The slowest ODR of at least 1.6x the loop rate: every frame holds a fresh sample.
  uint8_t code = static_cast<uint8_t>(drivers::adxl345::Rate::k100Hz);
  while (code < static_cast<uint8_t>(drivers::adxl345::Rate::k3200Hz) &&
         drivers::adxl345::RateHz(static_cast<drivers::adxl345::Rate>(code)) <
             1.6f * static_cast<float>(rate_hz)) {
    ++code;
  }
  s.rate = static_cast<drivers::adxl345::Rate>(code);
  return s;
}

drivers::adxl357::Settings Adxl357Settings(uint8_t range_g, uint16_t rate_hz) {
  drivers::adxl357::Settings s;
  s.range = range_g >= 40   ? drivers::adxl357::Range::k40g
            : range_g >= 20 ? drivers::adxl357::Range::k20g
                            : drivers::adxl357::Range::k10g;
  uint8_t code = static_cast<uint8_t>(drivers::adxl357::Odr::k62_5Hz);
  while (code > static_cast<uint8_t>(drivers::adxl357::Odr::k4000Hz) &&
         drivers::adxl357::OdrHz(static_cast<drivers::adxl357::Odr>(code)) <
             1.6f * static_cast<float>(rate_hz)) {
    --code;
  }
  s.odr = static_cast<drivers::adxl357::Odr>(code);
  return s;
}

drivers::bno055::Settings Bno055Settings(uint8_t range_g, uint16_t rate_hz) {
  drivers::bno055::Settings s;
  s.read_rate_hz = rate_hz;  // one read a loop
  s.range = range_g >= 16  ? drivers::bno055::Range::k16g
            : range_g >= 8 ? drivers::bno055::Range::k8g
            : range_g >= 4 ? drivers::bno055::Range::k4g
                           : drivers::bno055::Range::k2g;
  return s;
}

}  // namespace

float Mps2PerCount(uint8_t model, uint8_t range_g) {
  switch (static_cast<proto::SensorModel>(model)) {
    case proto::SensorModel::kAdxl345:
      return drivers::adxl345::kMps2PerCount;
    case proto::SensorModel::kAdxl357:
      return drivers::kStandardGravity *
             drivers::adxl357::GPerCount(Adxl357Settings(range_g, kMinRateHz).range);
    case proto::SensorModel::kBno055:
      return drivers::bno055::kMps2PerCount;
    default:
      return 0.0f;
  }
}

int32_t SaturationCounts(uint8_t model, uint8_t range_g) {
  // ADXL345 full resolution: 10 + log2(range / 2) bits, i.e. the output clips at -256 range and
  // 256 range - 1; at 1600 and 3200 Hz ODR the LSB is always 0 (datasheet, "Output Data Rate"),
  // so there the positive rail reads 256 range - 2. A reading at the rail or one LSB short of it
  // counts as saturated, whatever the ODR (the app picks the slowest ODR >= 1.6 x the loop
  // rate: 1600 Hz above 500 Hz).
  if (model == static_cast<uint8_t>(proto::SensorModel::kAdxl345)) {
    return 256 * static_cast<int32_t>(range_g) - 2;
  }
  const float per_count = Mps2PerCount(model, range_g);
  if (!(per_count > 0.0f)) return 0x7FFFFFFF;
  const float full_scale = static_cast<float>(range_g) * drivers::kStandardGravity / per_count;
  return static_cast<int32_t>(floorf(full_scale)) - 1;
}

CalibrationMap MakeCalibrationMap(const SensorConfig& s, const Calibration& k) {
  CalibrationMap m;
  m.saturated = false;
  const float rot = static_cast<float>(s.rotation_urad) * 1e-6f;
  const float c = cosf(rot), sn = sinf(rot);
  const float r[2][3] = {{c, -sn, 0.0f}, {sn, c, 0.0f}};  // link = R(rot) sensor
  const float scale = Mps2PerCount(s.model, s.range_g);
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 3; ++j) {
      float acc = 0.0f;
      for (int l = 0; l < 3; ++l) {
        acc += r[i][l] * (static_cast<float>(k.s_q24[3 * l + j]) / static_cast<float>(kOneQ24));
      }
      m.m_q30[i][j] = RoundToRaw(acc * scale, kTwo30, &m.saturated);
    }
    float off = 0.0f;
    for (int l = 0; l < 3; ++l) off += r[i][l] * static_cast<float>(k.o_umps2[l]) * 1e-6f;
    m.b_q16[i] = RoundToRaw(off, kTwo16, &m.saturated);
    // |b 2^14| < 2^45, |2^15 sum M| < 2^48: exact in 64 bits.
    const int64_t sum_m = static_cast<int64_t>(m.m_q30[i][0]) + m.m_q30[i][1] + m.m_q30[i][2];
    const int64_t base = static_cast<int64_t>(m.b_q16[i]) * 16384 - sum_m * 32768;
    const uint64_t u = static_cast<uint64_t>(base);
    m.base_lo[i] = static_cast<uint32_t>(u);
    m.base_hi[i] = static_cast<int32_t>(static_cast<uint32_t>(u >> 32));
  }
  return m;
}

#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
/// One axis of the 16-bit-count path on the AVR, in one assembly block with the 64-bit sum in
/// registers throughout (the C version spilled it: ~850 cycles a sensor, this ~560):
///   acc = base + sum_{j=0..2} m[j] u[j]   (m signed Q30, u unsigned 16-bit offset binary),
///   result = round_half_up(acc / 2^14) saturated to int32, *sat = 1 when it saturated
/// (core::detail::RoundShiftSaturate<14>'s value). Products by byte columns c = i + k (m_i u_k
/// at bytes c, c + 1), the carries out of byte c + 1 counted in t and added at byte c + 2 when
/// column c + 1 starts; m u = um u - 2^32 u [m < 0] (um = m as unsigned). Rounding: acc + 2^13,
/// shifted left by 2, so bytes 2..5 are (acc + 2^13) >> 14; it fits int32 iff bytes 6, 7 are the
/// sign extension of byte 5 (|acc| < 2^50, so the two bits shifted out are sign bits too).
JA_FORCE_INLINE int32_t CalibrateAxis(const int32_t* m, uint32_t base_lo, int32_t base_hi,
                                      const uint16_t* u, uint8_t* sat) {
  uint32_t lo = base_lo;
  uint32_t hi = static_cast<uint32_t>(base_hi);
  uint8_t m0, m1, m2, m3, u0, u1, t, s, n = 3;
  const uint8_t zero = 0;
  asm("1:\n\t"
      "ld %[m0], Z+\n\t"
      "ld %[m1], Z+\n\t"
      "ld %[m2], Z+\n\t"
      "ld %[m3], Z+\n\t"
      "ld %[u0], X+\n\t"
      "ld %[u1], X+\n\t"
      // column 0: m0 u0 at bytes 0, 1
      "mul %[m0], %[u0]\n\t"
      "add %A[lo], r0\n\t"
      "adc %B[lo], r1\n\t"
      "mov %[t], %[z]\n\t"
      "adc %[t], %[z]\n\t"
      // column 1: m1 u0, m0 u1 at bytes 1, 2
      "add %C[lo], %[t]\n\t"
      "mov %[t], %[z]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m1], %[u0]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m0], %[u1]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      // column 2: m2 u0, m1 u1 at bytes 2, 3
      "add %D[lo], %[t]\n\t"
      "mov %[t], %[z]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m2], %[u0]\n\t"
      "add %C[lo], r0\n\t"
      "adc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m1], %[u1]\n\t"
      "add %C[lo], r0\n\t"
      "adc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      // column 3: m3 u0, m2 u1 at bytes 3, 4
      "add %A[hi], %[t]\n\t"
      "mov %[t], %[z]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m3], %[u0]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m2], %[u1]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      // column 4: m3 u1 at bytes 4, 5
      "add %B[hi], %[t]\n\t"
      "mov %[t], %[z]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %[m3], %[u1]\n\t"
      "add %A[hi], r0\n\t"
      "adc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %C[hi], %[t]\n\t"
      "adc %D[hi], %[z]\n\t"
      // the sign of m
      "sbrs %[m3], 7\n\t"
      "rjmp 2f\n\t"
      "sub %A[hi], %[u0]\n\t"
      "sbc %B[hi], %[u1]\n\t"
      "sbc %C[hi], %[z]\n\t"
      "sbc %D[hi], %[z]\n\t"
      "2:\n\t"
      "dec %[n]\n\t"
      "breq 3f\n\t"
      "rjmp 1b\n\t"
      "3:\n\t"
      "clr __zero_reg__\n\t"
      // + 2^13, then << 2: bytes 2..5 = (acc + 2^13) >> 14
      "ldi %[t], 0x20\n\t"
      "add %B[lo], %[t]\n\t"
      "adc %C[lo], %[z]\n\t"
      "adc %D[lo], %[z]\n\t"
      "adc %A[hi], %[z]\n\t"
      "adc %B[hi], %[z]\n\t"
      "adc %C[hi], %[z]\n\t"
      "adc %D[hi], %[z]\n\t"
      "lsl %A[lo]\n\t"
      "rol %B[lo]\n\t"
      "rol %C[lo]\n\t"
      "rol %D[lo]\n\t"
      "rol %A[hi]\n\t"
      "rol %B[hi]\n\t"
      "rol %C[hi]\n\t"
      "rol %D[hi]\n\t"
      "lsl %A[lo]\n\t"
      "rol %B[lo]\n\t"
      "rol %C[lo]\n\t"
      "rol %D[lo]\n\t"
      "rol %A[hi]\n\t"
      "rol %B[hi]\n\t"
      "rol %C[hi]\n\t"
      "rol %D[hi]\n\t"
      // fits iff bytes 6, 7 = the sign extension of byte 5
      "mov %[t], %B[hi]\n\t"
      "lsl %[t]\n\t"
      "sbc %[t], %[t]\n\t"
      "clr %[s]\n\t"
      "cp %C[hi], %[t]\n\t"
      "cpc %D[hi], %[t]\n\t"
      "breq 4f\n\t"
      "inc %[s]\n\t"  // saturated: INT32_MAX, or INT32_MIN when negative
      "ldi %[t], 0xFF\n\t"
      "mov %C[lo], %[t]\n\t"
      "mov %D[lo], %[t]\n\t"
      "mov %A[hi], %[t]\n\t"
      "ldi %[t], 0x7F\n\t"
      "mov %B[hi], %[t]\n\t"
      "sbrs %D[hi], 7\n\t"
      "rjmp 4f\n\t"
      "clr %C[lo]\n\t"
      "clr %D[lo]\n\t"
      "clr %A[hi]\n\t"
      "ldi %[t], 0x80\n\t"
      "mov %B[hi], %[t]\n\t"
      "4:"
      : [lo] "+r"(lo), [hi] "+r"(hi), [mp] "+z"(m), [up] "+x"(u), [n] "+r"(n), [m0] "=&r"(m0),
        [m1] "=&r"(m1), [m2] "=&r"(m2), [m3] "=&r"(m3), [u0] "=&r"(u0), [u1] "=&r"(u1),
        [t] "=&d"(t), [s] "=&r"(s)
      : [z] "r"(zero)
      : "r0", "memory");
  *sat = s;
  return static_cast<int32_t>((lo >> 16) | (hi << 16));
}
#endif

LinkReading ApplyCalibration(const CalibrationMap& map, const drivers::RawSample& counts,
                             uint16_t* saturations) {
  using core::detail::Wide;
  const auto fits16 = [](int32_t c) {
    return static_cast<uint32_t>(c) + 32768u <= 65535u;  // -32768 <= c <= 32767
  };
  if (!fits16(counts.x) || !fits16(counts.y) || !fits16(counts.z)) {
    return ApplyCalibrationWide(map, counts, saturations);
  }
  // Offset binary: c = u - 2^15 with u = c + 2^15 in 0..65535, so
  // b 2^14 + sum_j M_j c_j = (b 2^14 - 2^15 sum_j M_j) + sum_j M_j u_j = base + sum_j M_j u_j,
  // the same sum as the reference, from 32 x 16-bit products (8 MULs each on the AVR).
  const uint16_t u[3] = {static_cast<uint16_t>(static_cast<uint16_t>(counts.x) ^ 0x8000u),
                         static_cast<uint16_t>(static_cast<uint16_t>(counts.y) ^ 0x8000u),
                         static_cast<uint16_t>(static_cast<uint16_t>(counts.z) ^ 0x8000u)};
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  uint8_t sat_x, sat_y;
  const int32_t x = CalibrateAxis(map.m_q30[0], map.base_lo[0], map.base_hi[0], u, &sat_x);
  const int32_t y = CalibrateAxis(map.m_q30[1], map.base_lo[1], map.base_hi[1], u, &sat_y);
  if ((sat_x | sat_y) != 0) *saturations = static_cast<uint16_t>(*saturations + 1);
  return LinkReading{x, y};
#else
  const uint16_t before = core::SaturationCount();
  int32_t out[2];
  for (int i = 0; i < 2; ++i) {
    Wide acc{map.base_lo[i], map.base_hi[i]};
    for (int j = 0; j < 3; ++j) {
      core::detail::AddWide(acc, core::detail::MultiplyWide32x16(map.m_q30[i][j], u[j]));
    }
    out[i] = core::detail::RoundShiftSaturate<14>(acc);
  }
  if (core::SaturationCount() != before) {
    *saturations = static_cast<uint16_t>(*saturations + 1);
    core::SaturationCount() = before;
  }
  return LinkReading{out[0], out[1]};
#endif
}

LinkReading ApplyCalibrationWide(const CalibrationMap& map, const drivers::RawSample& counts,
                                 uint16_t* saturations) {
  using core::detail::Wide;
  const int32_t v[3] = {counts.x, counts.y, counts.z};
  int32_t out[2];
  const uint16_t before = core::SaturationCount();
  for (int i = 0; i < 2; ++i) {
    // b * 2^30 / 2^16 = b << 14, then + sum M_ij counts_j, rounded once: Q30 -> Q16.
    Wide acc = core::detail::WidenRaw<14>(map.b_q16[i]);
    for (int j = 0; j < 3; ++j) {
      core::detail::AddWide(acc, core::detail::MultiplyWide(map.m_q30[i][j], v[j]));
    }
    out[i] = core::detail::RoundShiftSaturate<14>(acc);
  }
  if (core::SaturationCount() != before) {
    *saturations = static_cast<uint16_t>(*saturations + 1);
    core::SaturationCount() = before;
  }
  return LinkReading{out[0], out[1]};
}

drivers::I2cStatus SampleBus::Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) {
  switch (mode_) {
    case Mode::kForward:
      return target_->Read(addr7, reg, buf, n);
    case Mode::kCapture:
      captured_ = Transfer{addr7, reg, n};
      return drivers::I2cStatus::kBusError;  // the driver gives up without changing its state
    case Mode::kReplay:
      if (addr7 != captured_.addr7 || reg != captured_.reg || n != captured_.n) break;
      if (replay_status_ == drivers::I2cStatus::kOk) {
        for (uint8_t i = 0; i < n; ++i) buf[i] = replay_[i];
      }
      return replay_status_;
  }
  return drivers::I2cStatus::kBusError;  // a read the capture did not announce
}

drivers::I2cStatus SampleBus::Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) {
  if (mode_ == Mode::kForward) return target_->Write(addr7, reg, buf, n);
  return drivers::I2cStatus::kBusError;  // sampling never writes
}

void Sensor::DestroyDriver() {
  switch (kind_) {
    case Kind::kAdxl345:
      driver_.adxl345.~Adxl345();
      break;
    case Kind::kAdxl357:
      driver_.adxl357.~Adxl357();
      break;
    case Kind::kBno055:
      driver_.bno055.~Bno055();
      break;
    case Kind::kNone:
      break;
  }
  kind_ = Kind::kNone;
}

void Sensor::Bind(drivers::I2cBus& bus, drivers::Delay& delay, const SensorConfig& cfg,
                  const Calibration& cal, uint16_t rate_hz) {
  DestroyDriver();
  bus_ = &bus;
  sample_bus_.set_target(&bus);
  sample_bus_.Forward();
  sample_transfer_ = SampleBus::Transfer{0, 0, 0};
  address_ = cfg.address;
  model_ = cfg.model;
  range_g_ = cfg.range_g;
  rate_hz_ = rate_hz;
  switch (static_cast<proto::SensorModel>(cfg.model)) {
    case proto::SensorModel::kAdxl345:
      new (&driver_.adxl345) drivers::Adxl345(sample_bus_, cfg.address);
      kind_ = Kind::kAdxl345;
      break;
    case proto::SensorModel::kAdxl357:
      new (&driver_.adxl357) drivers::Adxl357(sample_bus_, cfg.address);
      kind_ = Kind::kAdxl357;
      break;
    case proto::SensorModel::kBno055:
      new (&driver_.bno055) drivers::Bno055(sample_bus_, delay, cfg.address);
      kind_ = Kind::kBno055;
      break;
    default:
      break;
  }
  const float periods = kFrozenSeconds * static_cast<float>(rate_hz);
  frozen_limit_ = periods < kMinFrozenPeriods ? kMinFrozenPeriods : static_cast<uint16_t>(periods);
  saturation_counts_ = SaturationCounts(cfg.model, cfg.range_g);
  SetCalibration(cfg, cal);
  counts_ = drivers::RawSample();
  reading_ = LinkReading{0, 0};
  chip_id_ = 0;
  fresh_ = 0;
  configured_ = false;
  needs_probe_ = bound();
  nack_ = wrong_id_ = saturated_ = has_value_ = false;
  unchanged_ = 0;
  nacks_ = id_errors_ = saturations_ = freezes_ = cal_saturations_ = 0;
}

void Sensor::SetCalibration(const SensorConfig& cfg, const Calibration& cal) {
  map_ = MakeCalibrationMap(cfg, cal);
  map_saturated_ = map_.saturated;
}

drivers::DeviceStatus Sensor::Configure() {
  switch (kind_) {
    case Kind::kAdxl345:
      return driver_.adxl345.Configure(Adxl345Settings(range_g_, rate_hz_));
    case Kind::kAdxl357:
      return driver_.adxl357.Configure(Adxl357Settings(range_g_, rate_hz_));
    case Kind::kBno055:
      return driver_.bno055.Configure(Bno055Settings(range_g_, rate_hz_));
    case Kind::kNone:
      break;
  }
  return drivers::DeviceStatus::kWrongId;
}

drivers::DeviceStatus Sensor::Read(drivers::RawSample* out) {
  switch (kind_) {
    case Kind::kAdxl345:
      // The data registers alone: Adxl345Settings picks an output data rate of at least 1.6x
      // the loop rate, so every loop finds a new conversion (-2 bytes and their TWI interrupts
      // a sensor a loop against reading INT_SOURCE for DATA_READY; a part that stops converting
      // shows as `frozen`, and CheckId's StillMeasuring then probes it again).
      return driver_.adxl345.ReadData(out);
    case Kind::kAdxl357:
      return driver_.adxl357.ReadData(out);  // likewise (Adxl357Settings: ODR >= 1.6x rate)
    case Kind::kBno055:
      return driver_.bno055.ReadSample(out);
    case Kind::kNone:
      break;
  }
  return drivers::DeviceStatus::kBusFault;
}

void Sensor::Probe() {
  if (!bound()) return;
  const drivers::DeviceStatus st = Configure();
  // The ID register as read from the chip, for hello (ADXL357: PARTID; 0 = no answer).
  const uint8_t id_reg = kind_ == Kind::kAdxl357 ? drivers::adxl357::kRegPartId : 0x00;
  uint8_t id = 0;
  if (drivers::ReadRegister(*bus_, address_, id_reg, &id) != drivers::I2cStatus::kOk) id = 0;
  chip_id_ = id;
  nack_ = st == drivers::DeviceStatus::kBusFault;
  wrong_id_ = st == drivers::DeviceStatus::kWrongId || st == drivers::DeviceStatus::kVerifyFailed;
  if (nack_) nacks_ = Increment(nacks_);
  if (wrong_id_) id_errors_ = Increment(id_errors_);
  configured_ = st == drivers::DeviceStatus::kOk;
  needs_probe_ = !configured_;
  if (configured_) {
    has_value_ = false;
    unchanged_ = 0;
    saturated_ = false;
  }
}

void Sensor::CheckId() {
  if (!bound() || !configured_) return;
  uint8_t reg = drivers::adxl345::kRegDevId, expected = drivers::adxl345::kDevId;
  if (kind_ == Kind::kAdxl357) {
    reg = drivers::adxl357::kRegPartId;
    expected = drivers::adxl357::kPartId;
  } else if (kind_ == Kind::kBno055) {
    reg = drivers::bno055::kRegChipId;  // page 0 in operation
    expected = drivers::bno055::kChipId;
  }
  uint8_t id = 0;
  if (drivers::ReadRegister(*bus_, address_, reg, &id) != drivers::I2cStatus::kOk) {
    nack_ = true;
    nacks_ = Increment(nacks_);
    configured_ = false;
    needs_probe_ = true;
    return;
  }
  chip_id_ = id;
  if (id != expected) {
    wrong_id_ = true;
    id_errors_ = Increment(id_errors_);
    configured_ = false;
    needs_probe_ = true;
    return;
  }
  if (unchanged_ >= frozen_limit_ && !StillMeasuring()) {
    // A part that reset by itself (a supply or connector glitch) answers with the right ID but
    // sits in standby (ADXL345, ADXL357) or CONFIG mode (BNO055): its output is frozen for good.
    // Probe it again, as a faulted sensor.
    configured_ = false;
    needs_probe_ = true;
  }
}

bool Sensor::StillMeasuring() {
  uint8_t reg = drivers::adxl345::kRegPowerCtl;
  if (kind_ == Kind::kAdxl357) reg = drivers::adxl357::kRegPowerCtl;
  if (kind_ == Kind::kBno055) reg = drivers::bno055::kRegOprMode;
  uint8_t v = 0;
  // A failed read says nothing about the mode: the next ID check and the samples catch a NACK.
  if (drivers::ReadRegister(*bus_, address_, reg, &v) != drivers::I2cStatus::kOk) return true;
  switch (kind_) {
    case Kind::kAdxl345:
      return (v & drivers::adxl345::kPowerMeasure) != 0;
    case Kind::kAdxl357:
      return (v & drivers::adxl357::kPowerStandby) == 0;
    case Kind::kBno055:
      return (v & 0x0Fu) == drivers::bno055::kModeAccOnly;
    case Kind::kNone:
      break;
  }
  return true;
}

void Sensor::Sample(uint8_t periods) {
  fresh_ = 0;
  cal_saturated_ = false;
  if (!bound() || !configured_) return;
  drivers::RawSample s;
  const drivers::DeviceStatus st = Read(&s);
  Account(st, s, periods);
}

// Inlined into both callers (Sample, CompleteSample's ADXL345 path): the sample then stays in
// registers instead of going through memory by reference.
__attribute__((always_inline)) inline void Sensor::Account(drivers::DeviceStatus st,
                                                           const drivers::RawSample& s,
                                                           uint8_t periods) {
  if (st == drivers::DeviceStatus::kBusFault) {
    nack_ = true;
    nacks_ = Increment(nacks_);
    configured_ = false;
    needs_probe_ = true;
    return;
  }
  nack_ = false;
  bool changed = false;
  if (st == drivers::DeviceStatus::kOk) {
    fresh_ = 1;
    changed = !has_value_ || s.x != counts_.x || s.y != counts_.y || s.z != counts_.z;
    counts_.x = s.x;  // field by field: the struct copy is a 12-pass byte loop on the AVR
    counts_.y = s.y;
    counts_.z = s.z;
    has_value_ = true;
    const uint16_t before = cal_saturations_;
    reading_ = ApplyCalibration(map_, counts_, &cal_saturations_);
    cal_saturated_ = cal_saturations_ != before;
    // c >= lim or c <= -lim - 1, i.e. c >= lim or ~c (= -c - 1) >= lim: one compare per axis
    // on c ^ sign(c) (= c when c >= 0, ~c otherwise).
    const int32_t lim = saturation_counts_;
    const auto beyond = [lim](int32_t c) { return (c ^ (c >> 31)) >= lim; };
    saturated_ = beyond(s.x) || beyond(s.y) || beyond(s.z);
    if (saturated_) saturations_ = Increment(saturations_);
  }
  if (changed) {
    unchanged_ = 0;
  } else if (unchanged_ < 0xFFFF) {
    // Counted in sample periods: a loop that overran spans more than one (APP.md "Timing"),
    // and an output unchanged for kFrozenSeconds is frozen however often the loop ran.
    const uint16_t before = unchanged_;
    unchanged_ = before < 0xFFFF - periods ? static_cast<uint16_t>(before + periods) : 0xFFFF;
    if (before < frozen_limit_ && unchanged_ >= frozen_limit_) freezes_ = Increment(freezes_);
  }
}

bool Sensor::PrepareSample(SampleBus::Transfer* t) {
  if (!bound() || !configured_) return false;
  if (sample_transfer_.n == 0) {
    // A driver's sample read has the same shape every time: learn it once per Bind.
    drivers::RawSample unused;
    sample_bus_.Capture();
    Read(&unused);
    sample_bus_.Forward();
    sample_transfer_ = sample_bus_.captured();
  }
  *t = sample_transfer_;
  return t->n != 0 && t->n <= kMaxSampleBytes;
}

void Sensor::CompleteSample(drivers::I2cStatus status, const uint8_t* data, uint8_t periods) {
  if (kind_ == Kind::kAdxl345 || kind_ == Kind::kAdxl357) {
    // The driver's ReadData on the batch's bytes (ADXL345 DATAX0..DATAZ1, ADXL357
    // XDATA3..ZDATA1: the read it announced) without the replay bus and the driver's virtual
    // calls, judged by the driver's own CheckData (a failed read is a bus fault, else the
    // decoded counts). ~0.6k cycles a sensor saved on the AVR.
    fresh_ = 0;
    cal_saturated_ = false;
    if (!configured_) return;
    drivers::RawSample s;
    const drivers::DeviceStatus st = kind_ == Kind::kAdxl345
                                         ? drivers::adxl345::CheckData(status, data, &s)
                                         : drivers::adxl357::CheckData(status, data, &s);
    Account(st, s, periods);
    return;
  }
  sample_bus_.Replay(status, data);
  Sample(periods);
  sample_bus_.Forward();
}

}  // namespace app
}  // namespace ja
