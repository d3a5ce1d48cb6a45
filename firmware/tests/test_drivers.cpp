// Driver tests against the recording fake bus: configuration sequences, read-back checks,
// fault paths (NACK, wrong ID, ignored writes), sample decoding and conversions.
#include <cstdint>

#include "check.hpp"
#include "drivers/adxl345.hpp"
#include "drivers/adxl357.hpp"
#include "drivers/bno055.hpp"
#include "drivers/tca9548a.hpp"
#include "fake_i2c_bus.hpp"

using ja::drivers::DeviceStatus;
using ja::drivers::RawSample;
using ja_test::FakeI2cBus;

namespace {

void TestTca9548aSelectsAndCaches() {
  FakeI2cBus bus;
  auto& mux = bus.Add(0x70);
  mux.no_register_pointer = true;
  ja::drivers::Tca9548a tca(bus, 0x70);
  CHECK(tca.Select(3) == DeviceStatus::kOk);
  CHECK_EQ(mux.regs[0], 0x08);
  CHECK_EQ(bus.log.size(), 1u);
  CHECK(bus.log[0].is_read);  // control write + read-back in one transaction
  CHECK_EQ(bus.log[0].reg, 0x08);
  CHECK(tca.Select(3) == DeviceStatus::kOk);  // cached: no traffic
  CHECK_EQ(bus.log.size(), 1u);
  CHECK(tca.Select(5) == DeviceStatus::kOk);
  CHECK_EQ(mux.regs[0], 0x20);
  CHECK(tca.Select(8) == DeviceStatus::kVerifyFailed);  // no channel 8
  CHECK(tca.Deselect() == DeviceStatus::kOk);
  CHECK_EQ(mux.regs[0], 0x00);
  CHECK_EQ(tca.select_count(), 3u);
}

void TestTca9548aReadBackMismatchAndNack() {
  FakeI2cBus bus;
  auto& mux = bus.Add(0x71);
  mux.no_register_pointer = true;
  mux.ignore_writes = true;  // stuck at 0: read-back shows the select did not take
  ja::drivers::Tca9548a tca(bus, 0x71);
  CHECK(tca.Select(1) == DeviceStatus::kVerifyFailed);
  ja::drivers::Tca9548a absent(bus, 0x75);
  CHECK(absent.Select(1) == DeviceStatus::kBusFault);
}

void SetUpAdxl345(ja_test::FakeDevice& d) { d.regs[ja::drivers::adxl345::kRegDevId] = 0xE5; }

void TestTca9548aChannelDecoratorRoutesIdenticalSensors() {
  FakeI2cBus bus;
  bus.Add(0x70).no_register_pointer = true;
  auto& s0 = bus.Add(0x53, 0);
  auto& s1 = bus.Add(0x53, 1);
  SetUpAdxl345(s0);
  SetUpAdxl345(s1);
  ja::drivers::Tca9548a tca(bus, 0x70);
  ja::drivers::Tca9548aChannel ch0(tca, 0), ch1(tca, 1);
  ja::drivers::Adxl345 a0(ch0, 0x53), a1(ch1, 0x53);
  CHECK(a0.Configure() == DeviceStatus::kOk);
  CHECK(a1.Configure() == DeviceStatus::kOk);
  s0.regs[0x30] = 0x80;
  s0.regs[0x32] = 0x10;  // x = 16
  s1.regs[0x30] = 0x80;
  s1.regs[0x32] = 0xF0;  // x = 0xFFF0 = -16
  s1.regs[0x33] = 0xFF;
  RawSample r0, r1;
  CHECK(a0.ReadSample(&r0) == DeviceStatus::kOk);
  CHECK(a1.ReadSample(&r1) == DeviceStatus::kOk);
  CHECK_EQ(r0.x, 16);
  CHECK_EQ(r1.x, -16);
  // Without the mux selecting its channel the sensor is unreachable.
  FakeI2cBus direct;
  direct.Add(0x70).no_register_pointer = true;
  SetUpAdxl345(direct.Add(0x53, 2));
  ja::drivers::Adxl345 hidden(direct, 0x53);
  CHECK(hidden.Configure() == DeviceStatus::kBusFault);
}

void TestAdxl345ConfigureSequence() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x53);
  SetUpAdxl345(d);
  ja::drivers::Adxl345 acc(bus, 0x53);
  ja::drivers::adxl345::Settings s;
  s.range = ja::drivers::adxl345::Range::k4g;
  s.rate = ja::drivers::adxl345::Rate::k800Hz;
  CHECK(acc.Configure(s) == DeviceStatus::kOk);
  // standby first, measure last; full-res + range; 800 Hz code 0x0D; data-ready enabled.
  CHECK(d.write_log.size() >= 2u);
  CHECK_EQ(d.write_log.front(), 0x2D);
  CHECK_EQ(d.write_log.back(), 0x2D);
  CHECK_EQ(d.regs[0x2D], 0x08);
  CHECK_EQ(d.regs[0x31], 0x09);
  CHECK_EQ(d.regs[0x2C], 0x0D);
  CHECK_EQ(d.regs[0x2E], 0x80);
  CHECK_EQ(d.regs[0x38], 0x00);
  CHECK_NEAR(ja::drivers::adxl345::RateHz(ja::drivers::adxl345::Rate::k800Hz), 800.0, 1e-3);
  CHECK_NEAR(ja::drivers::adxl345::RateHz(ja::drivers::adxl345::Rate::k100Hz), 100.0, 1e-3);
}

void TestAdxl345Faults() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x53);
  d.regs[0] = 0xE6;
  ja::drivers::Adxl345 acc(bus, 0x53);
  CHECK(acc.Configure() == DeviceStatus::kWrongId);
  d.regs[0] = 0xE5;
  d.ignore_writes = true;
  CHECK(acc.Configure() == DeviceStatus::kVerifyFailed);
  d.nack = true;
  CHECK(acc.Configure() == DeviceStatus::kBusFault);
  RawSample r;
  CHECK(acc.ReadSample(&r) == DeviceStatus::kBusFault);
}

void TestAdxl345SamplesAndFreshness() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x1D);
  SetUpAdxl345(d);
  ja::drivers::Adxl345 acc(bus, 0x1D);
  CHECK(acc.Configure() == DeviceStatus::kOk);
  RawSample r;
  r.x = 99;
  d.regs[0x30] = 0x00;  // DATA_READY clear
  CHECK(acc.ReadSample(&r) == DeviceStatus::kNotReady);
  CHECK_EQ(r.x, 99);
  CHECK_EQ(acc.fresh_count(), 0u);
  d.regs[0x30] = 0x80;
  const uint8_t data[6] = {0x00, 0x01, 0x00, 0xFF, 0x01, 0x80};  // 256, -256, -32767
  for (int i = 0; i < 6; ++i) d.regs[0x32 + i] = data[i];
  bus.log.clear();
  CHECK(acc.ReadSample(&r) == DeviceStatus::kOk);
  CHECK_EQ(bus.log.size(), 1u);  // one 8-byte transaction
  CHECK_EQ(bus.log[0].reg, 0x30);
  CHECK_EQ(bus.log[0].data.size(), 8u);
  CHECK_EQ(r.x, 256);
  CHECK_EQ(r.y, -256);
  CHECK_EQ(r.z, -32767);
  CHECK_EQ(acc.fresh_count(), 1u);
  // 256 counts at 3.9 mg/LSB = 0.9984 g.
  CHECK_NEAR(ja::drivers::CountsToMps2(r.x, ja::drivers::adxl345::kMps2PerCount),
             256 * 0.0039 * 9.80665, 1e-4);
}

void TestAdxl345ReadDataIsSixBytesWithoutDataReady() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x53);
  SetUpAdxl345(d);
  ja::drivers::Adxl345 acc(bus, 0x53);
  CHECK(acc.Configure() == DeviceStatus::kOk);
  d.regs[0x30] = 0x00;  // DATA_READY clear: not consulted (the caller's schedule says fresh)
  const uint8_t data[6] = {0x34, 0x12, 0xCC, 0xED, 0x00, 0x01};  // 0x1234, -0x1234, 256
  for (int i = 0; i < 6; ++i) d.regs[0x32 + i] = data[i];
  bus.log.clear();
  RawSample r;
  CHECK(acc.ReadData(&r) == DeviceStatus::kOk);
  CHECK_EQ(bus.log.size(), 1u);  // one 6-byte transaction from DATAX0
  CHECK_EQ(bus.log[0].reg, 0x32);
  CHECK_EQ(bus.log[0].data.size(), 6u);
  CHECK_EQ(r.x, 0x1234);
  CHECK_EQ(r.y, -0x1234);
  CHECK_EQ(r.z, 256);
  CHECK_EQ(acc.fresh_count(), 1u);
  d.nack = true;
  CHECK(acc.ReadData(&r) == DeviceStatus::kBusFault);
  CHECK_EQ(acc.fresh_count(), 1u);
}

void TestAdxl357() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x1D);
  d.regs[0] = 0xAD;
  d.regs[1] = 0x1D;
  d.regs[2] = 0xED;
  d.regs[0x2C] = 0x81;  // reset value: I2C_HS set, +-10 g
  d.regs[0x28] = 0x10;  // HPF setting to keep
  d.regs[0x2D] = 0x01;
  ja::drivers::Adxl357 acc(bus, 0x1D);
  ja::drivers::adxl357::Settings s;
  s.range = ja::drivers::adxl357::Range::k20g;
  s.odr = ja::drivers::adxl357::Odr::k1000Hz;
  CHECK(acc.Configure(s) == DeviceStatus::kOk);
  CHECK_EQ(d.regs[0x2C], 0x82);  // I2C_HS kept, range 20 g
  CHECK_EQ(d.regs[0x28], 0x12);  // HPF kept, ODR 1000 Hz
  CHECK_EQ(d.regs[0x2D], 0x00);  // measuring
  // Standby before range/filter writes, measurement last.
  CHECK_EQ(d.write_log.front(), 0x2D);
  CHECK_EQ(d.write_log.back(), 0x2D);
  CHECK_NEAR(ja::drivers::adxl357::OdrHz(ja::drivers::adxl357::Odr::k500Hz), 500.0, 1e-3);
  CHECK_NEAR(ja::drivers::adxl357::GPerCount(ja::drivers::adxl357::Range::k10g), 1.0 / 51200, 1e-9);
  CHECK_NEAR(ja::drivers::adxl357::GPerCount(ja::drivers::adxl357::Range::k40g), 1.0 / 12800, 1e-9);
  // 20-bit big-endian left-justified: +1, -1, max, min.
  const uint8_t plus1[3] = {0x00, 0x00, 0x10};
  const uint8_t minus1[3] = {0xFF, 0xFF, 0xF0};
  const uint8_t max[3] = {0x7F, 0xFF, 0xF0};
  const uint8_t min[3] = {0x80, 0x00, 0x00};
  CHECK_EQ(ja::drivers::adxl357::DecodeAxis(plus1), 1);
  CHECK_EQ(ja::drivers::adxl357::DecodeAxis(minus1), -1);
  CHECK_EQ(ja::drivers::adxl357::DecodeAxis(max), 524287);
  CHECK_EQ(ja::drivers::adxl357::DecodeAxis(min), -524288);
  // A sample: STATUS DATA_RDY, x = 51200 (1 g at +-10 g) = 0x0C800 -> bytes 0C 80 00.
  d.regs[0x04] = 0x01;
  d.regs[0x08] = 0x0C;
  d.regs[0x09] = 0x80;
  d.regs[0x0A] = 0x00;
  d.regs[0x0B] = 0xFF;
  d.regs[0x0C] = 0xFF;
  d.regs[0x0D] = 0xF0;
  RawSample r;
  CHECK(acc.ReadSample(&r) == DeviceStatus::kOk);
  CHECK_EQ(r.x, 51200);
  CHECK_EQ(r.y, -1);
  CHECK_EQ(acc.fresh_count(), 1u);
  // ReadData: XDATA3..ZDATA1 alone (9 bytes from 0x08), DATA_RDY not consulted.
  d.regs[0x04] = 0x00;
  d.regs[0x0E] = 0x00;
  d.regs[0x0F] = 0x00;
  d.regs[0x10] = 0x20;  // z = +2
  bus.log.clear();
  CHECK(acc.ReadData(&r) == DeviceStatus::kOk);
  CHECK_EQ(bus.log.size(), 1u);
  CHECK_EQ(bus.log[0].reg, 0x08);
  CHECK_EQ(bus.log[0].data.size(), 9u);
  CHECK_EQ(r.x, 51200);
  CHECK_EQ(r.y, -1);
  CHECK_EQ(r.z, 2);
  CHECK_EQ(acc.fresh_count(), 2u);
  d.regs[0x04] = 0x00;
  CHECK(acc.ReadSample(&r) == DeviceStatus::kNotReady);
  CHECK_EQ(acc.fresh_count(), 2u);
  d.regs[2] = 0xEC;
  CHECK(acc.Configure(s) == DeviceStatus::kWrongId);
}

void TestBno055() {
  FakeI2cBus bus;
  auto& d = bus.Add(0x28);
  d.paged = true;
  d.regs[0] = 0xA0;
  ja_test::FakeDelay delay;
  ja::drivers::Bno055 imu(bus, delay, 0x28);
  ja::drivers::bno055::Settings s;
  s.range = ja::drivers::bno055::Range::k8g;
  s.bandwidth = ja::drivers::bno055::Bandwidth::k500Hz;
  CHECK(imu.Configure(s) == DeviceStatus::kOk);
  CHECK_EQ(d.regs1[0x08], 0x02 | (6 << 2));  // page 1 ACC_Config
  CHECK_EQ(d.regs[0x3D], 0x01);              // ACCONLY
  CHECK_EQ(d.page, 0);
  CHECK_EQ(d.regs[0x3B], 0x00);  // m/s^2
  CHECK_EQ(delay.waits.size(), 2u);
  CHECK_EQ(delay.waits[0], 20u);  // -> CONFIG
  CHECK_EQ(delay.waits[1], 8u);   // -> ACCONLY
  // Order: CONFIG before the page-1 write, ACCONLY last.
  CHECK_EQ(d.write_log.back(), 0x3D);
  d.regs[0x08] = 0xE8;  // x = 1000 = 10.00 m/s^2
  d.regs[0x09] = 0x03;
  d.regs[0x0A] = 0x18;  // y = -1000
  d.regs[0x0B] = 0xFC;
  RawSample r;
  CHECK(imu.ReadSample(&r) == DeviceStatus::kOk);
  CHECK_EQ(r.x, 1000);
  CHECK_EQ(r.y, -1000);
  CHECK_NEAR(ja::drivers::CountsToMps2(r.x, ja::drivers::bno055::kMps2PerCount), 10.0, 1e-5);
  CHECK(imu.ReadSample(&r) == DeviceStatus::kNotReady);  // unchanged, rate unknown: not fresh
  CHECK_EQ(imu.fresh_count(), 1u);
  // Read no faster than the output data rate (500 Hz at 250 Hz bandwidth): an unchanged value
  // is a new conversion that happens to repeat (fresh); faster, it is the same one again.
  ja::drivers::bno055::Settings at_rate = s;
  at_rate.bandwidth = ja::drivers::bno055::Bandwidth::k250Hz;
  at_rate.read_rate_hz = 500;
  CHECK(imu.Configure(at_rate) == DeviceStatus::kOk);
  CHECK(imu.ReadSample(&r) == DeviceStatus::kOk);
  CHECK(imu.ReadSample(&r) == DeviceStatus::kOk);
  CHECK_EQ(r.x, 1000);
  at_rate.read_rate_hz = 1000;
  CHECK(imu.Configure(at_rate) == DeviceStatus::kOk);
  CHECK(imu.ReadSample(&r) == DeviceStatus::kOk);
  CHECK(imu.ReadSample(&r) == DeviceStatus::kNotReady);
  static_assert(ja::drivers::bno055::AccOdrHz(ja::drivers::bno055::Bandwidth::k250Hz) == 500,
                "ODR at 250 Hz bandwidth");
  d.regs[0] = 0xA1;
  CHECK(imu.Configure(s) == DeviceStatus::kWrongId);
  d.regs[0] = 0xA0;
  d.nack = true;
  CHECK(imu.Configure(s) == DeviceStatus::kBusFault);
}

void TestConversions() {
  using Q16 = ja::core::Fixed<16>;
  // 256 counts * 0.0383 m/s^2 per count, in Q16.16.
  const Q16 scale(0.0383f);
  const Q16 v = ja::drivers::CountsToFixed(256, scale);
  CHECK_EQ(v.raw(), 256 * scale.raw());
  CHECK_EQ(ja::drivers::SignExtend(0xFFFFF, 20), -1);
  CHECK_EQ(ja::drivers::SignExtend(0x7FFFF, 20), 524287);
  CHECK_EQ(ja::drivers::SignExtend(0x1000, 13), -4096);
  // Saturates instead of wrapping.
  ja::core::SaturationCount() = 0;
  const Q16 big = ja::drivers::CountsToFixed(524287, Q16(100.0f));
  CHECK_EQ(big.raw(), 0x7FFFFFFF);
  CHECK_EQ(ja::core::SaturationCount(), 1u);
}

}  // namespace

int main() {
  TestTca9548aSelectsAndCaches();
  TestTca9548aReadBackMismatchAndNack();
  TestTca9548aChannelDecoratorRoutesIdenticalSensors();
  TestAdxl345ConfigureSequence();
  TestAdxl345Faults();
  TestAdxl345SamplesAndFreshness();
  TestAdxl345ReadDataIsSixBytesWithoutDataReady();
  TestAdxl357();
  TestBno055();
  TestConversions();
  return ja_test::Finish("test_drivers");
}
