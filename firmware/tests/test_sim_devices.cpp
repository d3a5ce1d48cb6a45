// Virtual I2C devices (firmware/sim/devices): the bus state machine, each part's register map
// and conversions against datasheet facts (docs/sensors.md §A), the motion source, fault
// injection, the C ABI, and each part's own conversion clock (oscillator error and phase; the
// rig TOML's sim_clock_* fields to the attach spec).
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmath>
#include <string>

#include "check.hpp"
#include "platform/posix/rig_toml.hpp"
#include "sim/devices/adxl345.hpp"
#include "sim/devices/adxl357.hpp"
#include "sim/devices/bno055.hpp"
#include "sim/devices/bus.hpp"
#include "sim/devices/ja_sim_devices.h"
#include "sim/devices/motion.hpp"
#include "sim/devices/motion_csv.hpp"
#include "sim/devices/tca9548a.hpp"

using namespace ja::sim;

namespace {

constexpr double kG = kStandardGravity;
constexpr uint64_t kMs = 1000000;  // ns

uint8_t ReadReg(Bus& bus, uint8_t addr, uint8_t reg) {
  uint8_t v = 0;
  CHECK(bus.WriteRead(addr, &reg, 1, &v, 1) == I2cResult::kOk);
  return v;
}

I2cResult WriteReg(Bus& bus, uint8_t addr, uint8_t reg, uint8_t value) {
  const uint8_t b[2] = {reg, value};
  return bus.Write(addr, b, 2);
}

I2cResult ReadRegs(Bus& bus, uint8_t addr, uint8_t reg, uint8_t* out, size_t n) {
  return bus.WriteRead(addr, &reg, 1, out, n);
}

int16_t Le16(const uint8_t* b) { return static_cast<int16_t>(b[0] | (b[1] << 8)); }

int32_t Decode20(const uint8_t* d) {
  const uint32_t v =
      (static_cast<uint32_t>(d[0]) << 12) | (static_cast<uint32_t>(d[1]) << 4) | (d[2] >> 4);
  return (v & 0x80000u) ? static_cast<int32_t>(v) - (1 << 20) : static_cast<int32_t>(v);
}

// ---------------------------------------------------------------------------------------------
void TestBusStateMachine() {
  Bus bus;
  ConstantMotion still(0, 0, kG);
  Adxl345 a(0x53, &still);
  CHECK(bus.Attach(&a));
  CHECK(!bus.Attach(&a));  // attached once

  // Nobody at 0x10: address NACK.
  uint8_t v = 0;
  CHECK(bus.Read(0x10, &v, 1) == I2cResult::kAddressNack);
  CHECK_EQ(bus.counters().address_nacks, 1u);

  // Byte level: START, SLA+W, reg, Sr, SLA+R, 1 byte NACKed, STOP.
  bus.Start();
  CHECK(bus.WriteByte(0x53 << 1));
  CHECK(bus.WriteByte(Adxl345::kRegDevId));
  bus.Start();
  CHECK(bus.WriteByte((0x53 << 1) | 1));
  CHECK_EQ(bus.ReadByte(false), 0xE5);
  // After the master's NACK the device has released SDA: the line reads high.
  CHECK_EQ(bus.ReadByte(false), 0xFF);
  bus.Stop();
  CHECK_EQ(bus.counters().repeated_starts, 1u);
  CHECK_EQ(bus.counters().stops, 2u);

  // Data byte outside a transaction: bus error; STOP while idle: bus error.
  CHECK(!bus.WriteByte(0x00));
  bus.Stop();
  CHECK_EQ(bus.counters().bus_errors, 2u);

  // The register pointer survives a repeated START and auto-increments.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegBwRate, 0x0D) == I2cResult::kOk);
  uint8_t two[2] = {0, 0};
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegBwRate, two, 2) == I2cResult::kOk);
  CHECK_EQ(two[0], 0x0D);
  CHECK_EQ(two[1], 0x00);  // POWER_CTL
  // A multi-byte write auto-increments too.
  const uint8_t w[3] = {Adxl345::kRegOfsX, 0x01, 0x02};
  CHECK(bus.Write(0x53, w, 3) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegOfsX + 1), 0x02);

  // Two devices answering one address: both ACK, their bytes are wire-ANDed.
  Bus shared;
  Adxl345 p(0x1D), q(0x1D);
  CHECK(shared.Attach(&p));
  CHECK(shared.Attach(&q));
  CHECK(WriteReg(shared, 0x1D, Adxl345::kRegOfsX, 0x0F) == I2cResult::kOk);
  CHECK_EQ(ReadReg(shared, 0x1D, Adxl345::kRegOfsX), 0x0F);
  CHECK_EQ(p.counters().transactions, q.counters().transactions);

  // Bus time at 400 kHz: START + address + 1 byte + STOP = 20 SCL periods = 50 us.
  Bus timed;
  Adxl345 t(0x53);
  CHECK(timed.Attach(&t));
  timed.set_scl_hz(400000);
  const uint8_t one = 0x00;
  CHECK(timed.Write(0x53, &one, 1) == I2cResult::kOk);
  CHECK_EQ(timed.counters().scl_bits, 20u);
  CHECK_EQ(timed.time_ns(), 50000u);
  CHECK(!timed.SetTimeNs(10));  // never backwards
  CHECK_EQ(timed.time_ns(), 50000u);
}

// ---------------------------------------------------------------------------------------------
void TestMux() {
  Bus bus;
  Tca9548a mux(0x70);
  ConstantMotion m0(0.5 * kG, 0, 0), m1(-0.5 * kG, 0, 0);
  Adxl345 s0(0x53, &m0), s1(0x53, &m1);
  CHECK(bus.Attach(&mux));
  CHECK(bus.Attach(&s0, &mux, 0));
  CHECK(bus.Attach(&s1, &mux, 1));
  CHECK(!bus.Attach(&s1, &mux, 9));

  // Power-up: every channel off, the sensors are unreachable.
  uint8_t v = 0;
  CHECK_EQ(mux.control(), 0);
  CHECK(bus.Read(0x70, &v, 1) == I2cResult::kOk);
  CHECK_EQ(v, 0x00);
  CHECK(ReadRegs(bus, 0x53, 0, &v, 1) == I2cResult::kAddressNack);

  // The drivers' select: write the mask, repeated START, read it back, STOP.
  const uint8_t mask = 0x01;
  CHECK(bus.WriteRead(0x70, &mask, 1, &v, 1) == I2cResult::kOk);
  CHECK_EQ(v, 0x01);
  CHECK_EQ(mux.connected(), 0x01);
  CHECK_EQ(ReadReg(bus, 0x53, 0), 0xE5);
  CHECK(s0.counters().transactions > 0);
  CHECK_EQ(s1.counters().transactions, 0u);

  // The selection connects only at STOP: a device behind the new channel is not reachable
  // inside the selecting transaction.
  bus.Start();
  CHECK(bus.WriteByte(0x70 << 1));
  CHECK(bus.WriteByte(0x02));
  CHECK_EQ(mux.control(), 0x02);
  CHECK_EQ(mux.connected(), 0x01);
  bus.Start();
  const uint64_t before = s1.counters().transactions;
  CHECK(bus.WriteByte(0x53 << 1));  // s0 (still connected) answers, s1 does not
  bus.Stop();
  CHECK_EQ(s1.counters().transactions, before);
  CHECK_EQ(mux.connected(), 0x02);

  // A multi-byte write keeps the last byte; every read byte returns the control register.
  const uint8_t seq[3] = {0x01, 0x80, 0x02};
  CHECK(bus.Write(0x70, seq, 3) == I2cResult::kOk);
  uint8_t r[3] = {0, 0, 0};
  CHECK(bus.Read(0x70, r, 3) == I2cResult::kOk);
  CHECK(r[0] == 0x02 && r[1] == 0x02 && r[2] == 0x02);

  // Identical parts behind different channels are told apart.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegOfsX, 0x11) == I2cResult::kOk);  // s1 only
  CHECK(bus.Write(0x70, &mask, 1) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegOfsX), 0x00);  // s0 untouched

  // Nested multiplexer behind channel 7.
  Tca9548a inner(0x71);
  Adxl357 deep(0x1D);
  CHECK(bus.Attach(&inner, &mux, 7));
  CHECK(bus.Attach(&deep, &inner, 3));
  const uint8_t ch7 = 0x80, ch3 = 0x08;
  CHECK(bus.Write(0x70, &ch7, 1) == I2cResult::kOk);
  CHECK(ReadRegs(bus, 0x1D, 0, &v, 1) == I2cResult::kAddressNack);
  CHECK(bus.Write(0x71, &ch3, 1) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegPartId), 0xED);
  CHECK(bus.Write(0x70, &mask, 1) == I2cResult::kOk);  // outer channel 7 off again
  CHECK(ReadRegs(bus, 0x1D, 0, &v, 1) == I2cResult::kAddressNack);

  // /RESET clears the selection.
  mux.PulseReset();
  CHECK_EQ(mux.connected(), 0);
  CHECK(ReadRegs(bus, 0x53, 0, &v, 1) == I2cResult::kAddressNack);
}

// ---------------------------------------------------------------------------------------------
void TestAdxl345() {
  Bus bus;
  ConstantMotion m(0.5 * kG, -0.25 * kG, 1.0 * kG);
  Adxl345 a(0x53, &m);
  CHECK(bus.Attach(&a));

  // Power-up values (datasheet register map).
  CHECK_EQ(ReadReg(bus, 0x53, 0x00), 0xE5);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegBwRate), 0x0A);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegPowerCtl), 0x00);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegDataFormat), 0x00);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegIntSource), 0x02);
  // Standby: no conversions.
  bus.SetTimeNs(50 * kMs);
  CHECK_EQ(a.counters().samples, 0u);
  CHECK(!(ReadReg(bus, 0x53, Adxl345::kRegIntSource) & 0x80));

  // Full resolution +-2 g, 800 Hz, measure.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegBwRate, 0x0D) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegPowerCtl, 0x08) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 1250000u);  // 800 Hz
  bus.SetTimeNs(50 * kMs + 1300000);  // one conversion (grid instants k * 1.25 ms)
  CHECK_EQ(a.counters().samples, 1u);
  uint8_t b[8];
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegIntSource, b, 8) == I2cResult::kOk);
  CHECK(b[0] & 0x80);
  CHECK_EQ(Le16(b + 2), 128);  // 0.5 g / 3.9 mg
  CHECK_EQ(Le16(b + 4), -64);
  CHECK_EQ(Le16(b + 6), 256);
  // Reading the data cleared DATA_READY.
  CHECK(!(ReadReg(bus, 0x53, Adxl345::kRegIntSource) & 0x80));
  CHECK_EQ(a.counters().samples_read, 1u);

  // Unread conversions are overruns; OVERRUN shows in INT_SOURCE.
  bus.SetTimeNs(50 * kMs + 5000000);
  CHECK_EQ(a.counters().samples, 4u);
  CHECK_EQ(a.counters().overruns, 2u);
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegIntSource) & 0x81, 0x81);

  // Range and resolution: 10-bit +-16 g is 31.2 mg/LSB; full-res +-16 g keeps 3.9 mg/LSB.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x03) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 1250000);
  CHECK_EQ(a.counts(0), 16);  // round(0.5 / 0.0312)
  CHECK_EQ(a.counts(2), 32);
  // Saturation at the range: 3 g in full-res +-2 g -> 511 (10 bits).
  ConstantMotion big(3.0 * kG, -3.0 * kG, 20.0 * kG);
  a.set_motion(&big);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 1250000);
  CHECK_EQ(a.counts(0), 511);
  CHECK_EQ(a.counts(1), -512);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x0B) == I2cResult::kOk);  // +-16 g
  bus.SetTimeNs(bus.time_ns() + 1250000);
  CHECK_EQ(a.counts(0), 769);   // 3 g / 3.9 mg
  CHECK_EQ(a.counts(2), 4095);  // 13-bit rail
  a.set_motion(&m);

  // JUSTIFY (MSB aligned): full-res +-2 g is 10 bits -> shifted left by 6.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x0C) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 1250000);
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegDataX0, b, 6) == I2cResult::kOk);
  CHECK_EQ(Le16(b), 128 << 6);
  CHECK_EQ(Le16(b + 2), -64 * 64);

  // OFSX: 15.6 mg/LSB added -> +2 LSB of offset = +8 counts.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegOfsX, 0x02) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 1250000);
  CHECK_EQ(a.counts(0), 136);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegOfsX, 0x00) == I2cResult::kOk);

  // 3200 Hz: the LSB reads 0 (datasheet p.32).
  ConstantMotion odd(3 * 0.0039 * kG, 0, 0);
  a.set_motion(&odd);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegBwRate, 0x0F) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 312500u);
  bus.SetTimeNs(bus.time_ns() + 400000);
  CHECK_EQ(a.counts(0), 2);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegBwRate, 0x0A) == I2cResult::kOk);  // 100 Hz
  CHECK_EQ(a.period_ns(), 10000000u);
  bus.SetTimeNs(bus.time_ns() + 10 * kMs);
  CHECK_EQ(a.counts(0), 3);

  // Registers latch while addressed: time passing mid-read does not tear a sample.
  ConstantMotion later(-1.0 * kG, 0, 0);
  bus.Start();
  CHECK(bus.WriteByte(0x53 << 1));
  CHECK(bus.WriteByte(Adxl345::kRegDataX0));
  a.set_motion(&later);
  bus.SetTimeNs(bus.time_ns() + 30 * kMs);
  bus.Start();
  CHECK(bus.WriteByte((0x53 << 1) | 1));
  const uint8_t lo = static_cast<uint8_t>(bus.ReadByte(true));
  const uint8_t hi = static_cast<uint8_t>(bus.ReadByte(false));
  bus.Stop();
  CHECK_EQ(static_cast<int16_t>(lo | (hi << 8)), 3);
  CHECK_EQ(a.counts(0), -256);  // caught up at STOP

  // Read-only registers ignore writes.
  const uint64_t ignored = a.counters().writes_ignored;
  CHECK(WriteReg(bus, 0x53, 0x00, 0x12) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x53, 0x00), 0xE5);
  CHECK_EQ(a.counters().writes_ignored, ignored + 1);

  // SLEEP: conversions at the WAKEUP rate (8 Hz for 00).
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegPowerCtl, 0x0C) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 125 * kMs);
  // Standby stops conversions; power-on reset restores the map.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegPowerCtl, 0x00) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 0u);
  a.PowerOnReset();
  CHECK_EQ(ReadReg(bus, 0x53, Adxl345::kRegBwRate), 0x0A);
}

// ---------------------------------------------------------------------------------------------
void TestAdxl357() {
  Bus bus;
  ConstantMotion m(1.5 * kG, -0.3 * kG, 0.0);
  Adxl357 a(0x1D, &m);
  CHECK(bus.Attach(&a));

  uint8_t id[4];
  CHECK(ReadRegs(bus, 0x1D, 0x00, id, 4) == I2cResult::kOk);
  CHECK(id[0] == 0xAD && id[1] == 0x1D && id[2] == 0xED && id[3] == 0x01);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegPowerCtl), 0x01);  // standby at reset
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegRange), 0x81);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegFifoSamples), 0x60);
  uint8_t t[2];
  CHECK(ReadRegs(bus, 0x1D, Adxl357::kRegTemp2, t, 2) == I2cResult::kOk);
  CHECK_EQ((t[0] & 0x0F) << 8 | t[1], 1852);
  bus.SetTimeNs(10 * kMs);
  CHECK_EQ(a.counters().samples, 0u);  // standby

  // +-10 g, ODR 1000 Hz (code 2), measure.
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegFilter, 0x02) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegPowerCtl, 0x00) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 1000000u);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegStatus) & 1, 0);
  bus.SetTimeNs(11 * kMs + 1);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegStatus) & 1, 1);
  uint8_t d[13];
  CHECK(ReadRegs(bus, 0x1D, Adxl357::kRegStatus, d, 13) == I2cResult::kOk);
  CHECK_EQ(d[0] & 1, 1);
  // 1.5 g * 51200 = 76800 = 0x12C00: big-endian, left-justified in 20 bits.
  CHECK(d[4] == 0x12 && d[5] == 0xC0 && d[6] == 0x00);
  CHECK_EQ(Decode20(d + 4), 76800);
  CHECK_EQ(Decode20(d + 7), -15360);
  CHECK_EQ(Decode20(d + 10), 0);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegStatus) & 1, 0);  // cleared by the data read

  // A value with a non-zero low nibble, +-20 g (25600 LSB/g), in standby as drivers do.
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegPowerCtl, 0x01) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegRange, 0x82) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegPowerCtl, 0x00) == I2cResult::kOk);
  CHECK_EQ(a.counters().config_violations, 0u);
  ConstantMotion n(25601.0 / 25600.0 * kG, 0, 0);
  a.set_motion(&n);
  bus.SetTimeNs(bus.time_ns() + kMs);
  CHECK(ReadRegs(bus, 0x1D, Adxl357::kRegXData3, d, 3) == I2cResult::kOk);
  CHECK(d[0] == 0x06 && d[1] == 0x40 && d[2] == 0x10);

  // Saturation at 20 bits: 12 g at +-10 g.
  ConstantMotion big(12.0 * kG, -12.0 * kG, 0);
  a.set_motion(&big);
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegRange, 0x81) == I2cResult::kOk);  // while measuring
  CHECK_EQ(a.counters().config_violations, 1u);
  bus.SetTimeNs(bus.time_ns() + kMs);
  CHECK_EQ(a.counts(0), 524287);
  CHECK_EQ(a.counts(1), -524288);

  // ODR codes: 4000 Hz / 2^code; 10 = 3.906 Hz.
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegFilter, 0x0A) == I2cResult::kOk);
  CHECK_EQ(a.period_ns(), 256000000u);
  // RESET 0x52: back to power-up values (standby).
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegReset, 0x52) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegPowerCtl), 0x01);
  CHECK_EQ(ReadReg(bus, 0x1D, Adxl357::kRegFilter), 0x00);
  CHECK_EQ(a.period_ns(), 0u);
}

// ---------------------------------------------------------------------------------------------
void TestBno055() {
  Bus bus;
  ConstantMotion m(1.23, -4.56, 9.81);
  m.SetGyro(1.0, -0.5, 0.0);
  Bno055 b(0x28, &m);
  CHECK(bus.Attach(&b));

  uint8_t id[4];
  CHECK(ReadRegs(bus, 0x28, 0x00, id, 4) == I2cResult::kOk);
  CHECK(id[0] == 0xA0 && id[1] == 0xFB && id[2] == 0x32 && id[3] == 0x0F);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegPageId), 0);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegOprMode), 0x00);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegUnitSel), 0x80);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegSysStatus), 0);
  // Page 1: ACC_Config power-up 0x0D (4 g, 62.5 Hz); PAGE_ID reads 1 there.
  CHECK(WriteReg(bus, 0x28, Bno055::kRegPageId, 1) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegPageId), 1);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegAccConfig), 0x0D);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegGyrConfig0), 0x38);
  // 2 g, 250 Hz bandwidth (code 5) -> ODR 500 Hz.
  CHECK(WriteReg(bus, 0x28, Bno055::kRegAccConfig, 0x14) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegAccConfig), 0x14);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegPageId, 0) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegUnitSel, 0x00) == I2cResult::kOk);

  // CONFIG -> ACCONLY takes 7 ms: OPR_MODE reads the request at once, data starts after.
  bus.SetTimeNs(100 * kMs);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegOprMode, 0x01) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegOprMode), 0x01);
  CHECK(b.switching());
  // Writes during the switch are dropped.
  const uint64_t ignored = b.counters().writes_ignored;
  CHECK(WriteReg(bus, 0x28, Bno055::kRegUnitSel, 0x01) == I2cResult::kOk);
  CHECK_EQ(b.counters().writes_ignored, ignored + 1);
  bus.SetTimeNs(106 * kMs);
  CHECK_EQ(b.counters().samples, 0u);
  CHECK(b.switching());
  bus.SetTimeNs(107 * kMs);
  CHECK(!b.switching());
  CHECK_EQ(b.active_mode(), 0x01);
  CHECK_EQ(b.accel_period_ns(), 2000000u);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegSysStatus), 6);
  bus.SetTimeNs(109 * kMs + 1);
  CHECK_EQ(b.counters().samples, 1u);
  uint8_t d[6];
  CHECK(ReadRegs(bus, 0x28, Bno055::kRegAccData, d, 6) == I2cResult::kOk);
  CHECK_EQ(Le16(d), 123);  // 1 m/s^2 = 100 LSB
  CHECK_EQ(Le16(d + 2), -456);
  CHECK_EQ(Le16(d + 4), 981);
  // ACCONLY has no gyro.
  CHECK(ReadRegs(bus, 0x28, Bno055::kRegGyrData, d, 6) == I2cResult::kOk);
  CHECK_EQ(Le16(d), 0);
  // Sensor configuration is refused outside CONFIG mode.
  CHECK(WriteReg(bus, 0x28, Bno055::kRegPageId, 1) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegAccConfig, 0x0D) == I2cResult::kOk);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegAccConfig), 0x14);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegPageId, 0) == I2cResult::kOk);
  // UNIT_SEL mg: 1 LSB = 1 mg.
  CHECK(WriteReg(bus, 0x28, Bno055::kRegUnitSel, 0x01) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 2 * kMs);
  CHECK_EQ(b.accel_counts(0), 125);  // 1.23 / 9.80665 g
  // Range 2 g: 25 m/s^2 clips at 2 g.
  ConstantMotion big(25.0, 0, 0);
  b.set_motion(&big);
  bus.SetTimeNs(bus.time_ns() + 2 * kMs);
  CHECK_EQ(b.accel_counts(0), 2000);

  // ACCONLY -> CONFIG takes 19 ms; then AMG (accel + gyro).
  b.set_motion(&m);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegOprMode, 0x00) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 18 * kMs);
  CHECK(b.switching());
  bus.SetTimeNs(bus.time_ns() + 1 * kMs);
  CHECK(!b.switching());
  CHECK_EQ(b.active_mode(), 0x00);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegUnitSel, 0x00) == I2cResult::kOk);
  // Axis remap: X <- Y, Y <- X (0x21), X negated (sign bit2).
  CHECK(WriteReg(bus, 0x28, Bno055::kRegAxisMapConfig, 0x21) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegAxisMapSign, 0x04) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x28, Bno055::kRegOprMode, Bno055::kModeAmg) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(b.accel_counts(0), 456);
  CHECK_EQ(b.accel_counts(1), 123);
  // Gyro 16 LSB/dps: -0.5 rad/s on y becomes +x: 458.4 LSB; 1 rad/s on x -> y: 916.7.
  CHECK_EQ(b.gyro_counts(0), 458);
  CHECK_EQ(b.gyro_counts(1), 917);

  // RST_SYS: the part NACKs while it boots (650 ms), then reads power-up values.
  CHECK(WriteReg(bus, 0x28, Bno055::kRegSysTrigger, 0x20) == I2cResult::kOk);
  uint8_t v;
  CHECK(ReadRegs(bus, 0x28, 0x00, &v, 1) == I2cResult::kAddressNack);
  bus.SetTimeNs(bus.time_ns() + 649 * kMs);
  CHECK(ReadRegs(bus, 0x28, 0x00, &v, 1) == I2cResult::kAddressNack);
  bus.SetTimeNs(bus.time_ns() + 1 * kMs);
  CHECK_EQ(ReadReg(bus, 0x28, 0x00), 0xA0);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegOprMode), 0x00);
  CHECK_EQ(ReadReg(bus, 0x28, Bno055::kRegAxisMapConfig), 0x24);
  CHECK(b.counters().address_nacks >= 2u);
}

// ---------------------------------------------------------------------------------------------
void TestFaults() {
  Bus bus;
  Tca9548a mux(0x70);
  ConstantMotion m(0.5 * kG, -0.1 * kG, 1.0 * kG);
  Adxl345 a(0x53, &m);
  Adxl357 c(0x1D, &m);
  Bno055 b(0x28, &m);
  CHECK(bus.Attach(&mux));
  CHECK(bus.Attach(&a, &mux, 0));
  CHECK(bus.Attach(&c, &mux, 0));
  CHECK(bus.Attach(&b, &mux, 0));
  const uint8_t ch0 = 0x01;
  CHECK(bus.Write(0x70, &ch0, 1) == I2cResult::kOk);

  // NACK on the address; cleared, the part answers again.
  uint8_t v = 0;
  CHECK(a.SetFault(FaultKind::kNack, true));
  CHECK(ReadRegs(bus, 0x53, 0, &v, 1) == I2cResult::kAddressNack);
  CHECK_EQ(a.counters().address_nacks, 1u);
  CHECK(a.SetFault(FaultKind::kNack, false));
  CHECK_EQ(ReadReg(bus, 0x53, 0), 0xE5);
  // NACK on data (param 1): the address is ACKed, the register byte is not.
  CHECK(c.SetFault(FaultKind::kNack, true, 1));
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegPowerCtl, 0x00) == I2cResult::kDataNack);
  c.ClearFaults();
  // Intermittent NACK (param 3): every third address phase is refused.
  CHECK(a.SetFault(FaultKind::kNack, true, 3));
  int refused = 0;
  for (int i = 0; i < 9; ++i) {
    if (ReadRegs(bus, 0x53, 0, &v, 1) == I2cResult::kAddressNack) ++refused;
  }
  CHECK_EQ(refused, 3);
  a.ClearFaults();

  // Wrong ID: complement by default, or the given value.
  CHECK(a.SetFault(FaultKind::kWrongId, true));
  CHECK_EQ(ReadReg(bus, 0x53, 0), static_cast<uint8_t>(~0xE5));
  CHECK(b.SetFault(FaultKind::kWrongId, true, 0x55));
  CHECK_EQ(ReadReg(bus, 0x28, 0), 0x55);
  CHECK(c.SetFault(FaultKind::kWrongId, true, 0x00));
  uint8_t id[3];
  CHECK(ReadRegs(bus, 0x1D, 0, id, 3) == I2cResult::kOk);
  CHECK(id[0] == 0x52 && id[2] == 0x12);
  a.ClearFaults();
  b.ClearFaults();
  c.ClearFaults();

  // Saturation: rails with the input's sign; axis mask.
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegPowerCtl, 0x08) == I2cResult::kOk);
  CHECK(a.SetFault(FaultKind::kSaturate, true, 0x3));  // x and y
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(a.counts(0), 511);
  CHECK_EQ(a.counts(1), -512);
  CHECK_EQ(a.counts(2), 256);
  a.ClearFaults();
  CHECK(WriteReg(bus, 0x1D, Adxl357::kRegPowerCtl, 0x00) == I2cResult::kOk);
  CHECK(c.SetFault(FaultKind::kSaturate, true));
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(c.counts(0), 524287);
  CHECK_EQ(c.counts(1), -524288);
  c.ClearFaults();

  // Frozen (param 0): data-ready keeps coming, the values stay.
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(a.counts(0), 128);
  CHECK(a.SetFault(FaultKind::kFrozen, true));
  ConstantMotion other(-0.5 * kG, 0, 0);
  a.set_motion(&other);
  uint8_t s[8];
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegIntSource, s, 8) == I2cResult::kOk);
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegIntSource, s, 8) == I2cResult::kOk);
  CHECK(s[0] & 0x80);
  CHECK_EQ(Le16(s + 2), 128);
  // Frozen (param 1): the conversions stop.
  CHECK(a.SetFault(FaultKind::kFrozen, true, 1));
  const uint64_t samples = a.counters().samples;
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(a.counters().samples, samples);
  CHECK(!(ReadReg(bus, 0x53, Adxl345::kRegIntSource) & 0x80));
  a.ClearFaults();
  bus.SetTimeNs(bus.time_ns() + 20 * kMs);
  CHECK_EQ(a.counts(0), -128);

  // Multiplexer: wrong read-back, frozen selection, no saturation.
  CHECK(mux.SetFault(FaultKind::kWrongId, true));
  CHECK(bus.WriteRead(0x70, &ch0, 1, &v, 1) == I2cResult::kOk);
  CHECK_EQ(v, 0xFE);
  mux.ClearFaults();
  CHECK(mux.SetFault(FaultKind::kFrozen, true));
  const uint8_t ch1 = 0x02;
  CHECK(bus.Write(0x70, &ch1, 1) == I2cResult::kOk);
  CHECK_EQ(mux.connected(), 0x01);
  CHECK(!mux.SetFault(FaultKind::kSaturate, true));
  mux.ClearFaults();
  CHECK(mux.SetFault(FaultKind::kNack, true));
  CHECK(bus.Write(0x70, &ch1, 1) == I2cResult::kAddressNack);
  CHECK_EQ(mux.connected(), 0x01);
}

// ---------------------------------------------------------------------------------------------
void TestMotion(const std::string& dir) {
  MotionTrack t;
  const double a0[3] = {0, 1, 2}, a1[3] = {10, 11, 12}, a2[3] = {20, 21, 22};
  CHECK(t.Append(0.0, a0, nullptr));
  CHECK(t.Append(0.01, a1, nullptr));
  CHECK(t.Append(0.02, a2, nullptr));
  CHECK(!t.Append(0.02, a2, nullptr));  // times must increase
  MotionSample s;
  CHECK(t.Sample(5000000, &s));  // 5 ms: half way
  CHECK_NEAR(s.accel_mps2[0], 5.0, 1e-9);
  CHECK(t.Sample(10000000, &s));
  CHECK_NEAR(s.accel_mps2[1], 11.0, 1e-9);
  CHECK(t.Sample(999000000, &s));  // after the end: hold
  CHECK_NEAR(s.accel_mps2[2], 22.0, 1e-9);
  t.set_loop(true);  // period 30 ms
  CHECK(t.Sample(35000000, &s));
  CHECK_NEAR(s.accel_mps2[0], 5.0, 1e-9);
  CHECK(!s.has_gyro);

  // CSV: header, rows, errors name line and field.
  NamedTracks tracks;
  std::string err;
  CHECK(
      ParseAccelCsv("t,a.0.x,a.0.y,a.0.z,b.1.x,b.1.y,b.1.z,b.1.gx,b.1.gy,b.1.gz,theta\n"
                    "0,1,2,3,4,5,6,0.1,0.2,0.3,0\n0.01,2,3,4,5,6,7,0.2,0.3,0.4,0\n",
                    &tracks, &err));
  CHECK_EQ(tracks.size(), 2u);
  CHECK(tracks[0].first == "a.0" && tracks[1].first == "b.1");
  CHECK(tracks[1].second->Sample(10000000, &s));
  CHECK(s.has_gyro);
  CHECK_NEAR(s.gyro_rps[2], 0.4, 1e-12);
  CHECK(!ParseAccelCsv("t,a.0.x,a.0.y,a.0.z\n0,1,2,3\n0.01,1,zz,3\n", &tracks, &err));
  CHECK(err.find("line 3") != std::string::npos && err.find("a.0.y") != std::string::npos);
  CHECK(!ParseAccelCsv("t,a.0.x,a.0.z\n0,1,2\n", &tracks, &err));
  CHECK(err.find("a.0") != std::string::npos);
  CHECK(!ParseAccelCsv("t,a.0.x,a.0.y,a.0.z\n0,1,2\n", &tracks, &err));
  CHECK(err.find("line 2") != std::string::npos);
  CHECK(!ParseAccelCsv("t,a.0.x,a.0.y,a.0.z\n0.1,1,2,3\n0.05,1,2,3\n", &tracks, &err));
  CHECK(!LoadAccelCsv((dir + "/no_such_file.csv").c_str(), &tracks, &err));

  // A device samples the series on its own ODR grid: at 100 Hz with 100 Hz rows each
  // conversion is exactly a row.
  const std::string path = dir + "/sim_devices_motion.csv";
  FILE* f = fopen(path.c_str(), "w");
  CHECK(f != nullptr);
  if (!f) return;
  fprintf(f, "t,a.0.x,a.0.y,a.0.z\n");
  for (int i = 0; i <= 100; ++i) {
    fprintf(f, "%.2f,%.9f,%.9f,%.9f\n", i * 0.01, 0.0390 * i * kG / 10.0, -0.0039 * i * kG, kG);
  }
  fclose(f);
  CHECK(LoadAccelCsv(path.c_str(), &tracks, &err));
  Bus bus;
  Adxl345 a(0x53, tracks[0].second.get());
  CHECK(bus.Attach(&a));
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
  CHECK(WriteReg(bus, 0x53, Adxl345::kRegPowerCtl, 0x08) == I2cResult::kOk);  // 100 Hz
  for (int i = 1; i <= 50; ++i) {
    bus.SetTimeNs(static_cast<uint64_t>(i) * 10 * kMs + 3 * kMs);  // between rows
    uint8_t b[8];
    CHECK(ReadRegs(bus, 0x53, Adxl345::kRegIntSource, b, 8) == I2cResult::kOk);
    CHECK(b[0] & 0x80);
    CHECK_EQ(Le16(b + 2), i);
    CHECK_EQ(Le16(b + 4), -i);
    CHECK_EQ(Le16(b + 6), 256);
  }
  CHECK_EQ(a.counters().overruns, 0u);
  CHECK_EQ(a.counters().samples_read, 50u);
}

// ---------------------------------------------------------------------------------------------
void TestCAbi(const std::string& dir) {
  CHECK_EQ(ja_sim_abi_version(), JA_SIM_ABI_VERSION);
  CHECK_EQ(ja_sim_add_device(nullptr, JA_SIM_ADXL345, 0x53, -1, 0, "a.0"), JA_SIM_EINVAL);
  ja_sim* sim = ja_sim_create();
  CHECK(sim != nullptr);
  CHECK_EQ(ja_sim_attach_rig(sim, "a.0 adxl345 0x53 0\na.1 adxl345 0x53 9\n"), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("line 2") != std::string::npos);
  CHECK_EQ(ja_sim_attach_rig(sim, "a.0 gizmo 0x53 0\n"), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_device_count(sim), 0);
  CHECK_EQ(ja_sim_attach_rig(sim,
                             "# rig\nmux 0x70\na.0 adxl345 0x53 0\na.1 adxl357 0x1D 1\n"
                             "b.0 bno055 0x28 2\nb.1 adxl345 83 -1\n"),
           4);
  CHECK_EQ(ja_sim_device_count(sim), 5);  // + the multiplexer
  int model = 0, addr = 0, mux = 0, channel = 0;
  CHECK_EQ(ja_sim_device_info(sim, ja_sim_find_device(sim, "a.1"), &model, &addr, &mux, &channel),
           JA_SIM_OK);
  CHECK(model == JA_SIM_ADXL357 && addr == 0x1D && mux == 0 && channel == 1);
  CHECK_EQ(ja_sim_device_info(sim, 0, &model, &addr, &mux, &channel), JA_SIM_OK);
  CHECK(model == JA_SIM_TCA9548A && addr == 0x70 && mux == -1);

  const std::string path = dir + "/sim_devices_cabi.csv";
  FILE* f = fopen(path.c_str(), "w");
  CHECK(f != nullptr);
  if (!f) return;
  fprintf(f, "t,a.0.x,a.0.y,a.0.z,b.1.x,b.1.y,b.1.z\n");
  for (int i = 0; i < 10; ++i) fprintf(f, "%.2f,%.9f,0,0,0,%.9f,0\n", i * 0.01, 0.25 * kG, -kG);
  fclose(f);
  CHECK_EQ(ja_sim_load_motion_csv(sim, (dir + "/missing.csv").c_str()), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_load_motion_csv(sim, path.c_str()), 2);  // a.0 and b.1 have columns

  // b.1 is on the root bus; a.0 behind channel 0.
  uint8_t reg = 0x2D, on[2] = {0x2D, 0x08}, v = 0;
  CHECK_EQ(ja_sim_i2c_write(sim, 0x53, on, 2), JA_SIM_OK);  // b.1 measure at 100 Hz
  CHECK_EQ(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, &v, 1), JA_SIM_OK);
  CHECK_EQ(v, 0x08);
  CHECK_EQ(ja_sim_set_time_us(sim, 20000), JA_SIM_OK);
  CHECK_EQ(ja_sim_set_time_us(sim, 10000), 1);
  uint8_t b[6];
  reg = 0x32;
  CHECK_EQ(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, b, 6), JA_SIM_OK);
  CHECK_EQ(Le16(b + 2), -256);  // 10-bit +-2 g: 3.9 mg/LSB
  // Byte level.
  CHECK_EQ(ja_sim_bus_start(sim), JA_SIM_OK);
  CHECK_EQ(ja_sim_bus_write_byte(sim, 0x70 << 1), 1);
  CHECK_EQ(ja_sim_bus_write_byte(sim, 0x01), 1);
  CHECK_EQ(ja_sim_bus_stop(sim), JA_SIM_OK);
  CHECK_EQ(ja_sim_bus_start(sim), JA_SIM_OK);
  CHECK_EQ(ja_sim_bus_write_byte(sim, 0x70 << 1 | 1), 1);
  CHECK_EQ(ja_sim_bus_read_byte(sim, 0), 0x01);
  CHECK_EQ(ja_sim_bus_stop(sim), JA_SIM_OK);
  // Faults through the ABI.
  const int a0 = ja_sim_find_device(sim, "a.0");
  CHECK_EQ(ja_sim_inject_fault(sim, a0, JA_SIM_FAULT_NACK, 0), JA_SIM_OK);
  reg = 0;
  CHECK_EQ(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, &v, 1), JA_SIM_OK);  // b.1 still answers
  ja_sim_device_counters dc;
  CHECK_EQ(ja_sim_get_device_counters(sim, a0, &dc, sizeof dc), JA_SIM_OK);
  CHECK_EQ(dc.address_nacks, 2u);
  CHECK_EQ(ja_sim_get_device_counters(sim, a0, &dc, 8), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_clear_fault(sim, a0, 0), JA_SIM_OK);
  CHECK_EQ(ja_sim_inject_fault(sim, 0, JA_SIM_FAULT_SATURATE, 0), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("tca9548a") != std::string::npos);
  const double pose[3] = {0, 0, kG};
  CHECK_EQ(ja_sim_set_constant_motion(sim, a0, pose, nullptr), JA_SIM_OK);
  CHECK_EQ(ja_sim_power_cycle(sim, a0), JA_SIM_OK);
  ja_sim_bus_counters bc;
  CHECK_EQ(ja_sim_get_bus_counters(sim, &bc, sizeof bc), JA_SIM_OK);
  CHECK(bc.stops >= 5u && bc.address_acks >= 5u);
  // Arrays instead of a file; scl charging.
  const double ts[2] = {0.0, 1.0}, acc[6] = {0, 0, 0, 1, 2, 3};
  CHECK_EQ(ja_sim_set_motion(sim, "b.0", 2, ts, acc, nullptr), 3);  // a.0, b.0, b.1
  CHECK_EQ(ja_sim_set_scl_hz(sim, 400000), JA_SIM_OK);
  const uint64_t t0 = ja_sim_time_ns(sim);
  CHECK_EQ(ja_sim_i2c_write(sim, 0x53, on, 2), JA_SIM_OK);
  CHECK_EQ(ja_sim_time_ns(sim) - t0, 72500u);  // 29 SCL periods
  ja_sim_destroy(sim);
}

// ---------------------------------------------------------------------------------------------
// The conversion clock with the part's oscillator (sampling.hpp): t_j = O + j P,
// P = floor(P_nom / (1 + ppm 1e-6) + 0.5), O = floor(phase P + 0.5).
void TestSampleClock() {
  // Defaults: the grid k * P_nom from device time 0, as the clock always had it (reference: the
  // newest instant floor(now / P) * P, counts as differences of floor(now / P)).
  {
    SampleClock c;
    const uint64_t p = 1250000;
    uint64_t now = 12345, t = 0;
    c.Start(now, p);
    CHECK_EQ(c.period_ns(), p);
    CHECK_EQ(c.offset_ns(), 0u);
    uint64_t k_prev = now / p;
    bool same = true;
    for (int i = 0; i < 20000; ++i) {
      now += 1 + (static_cast<uint64_t>(i) * 7919u) % 3000000u;
      const uint64_t n = c.Advance(now, &t);
      const uint64_t k = now / p;
      same = same && n == k - k_prev && (n == 0 || t == k * p);
      k_prev = k;
    }
    CHECK(same);
  }
  // +20000 ppm (fast), phase 0.3, 100 Hz: P = 9803922 ns, O = 2941177 ns.
  CHECK_EQ(EffectivePeriodNs(10000000, 20000.0), 9803922u);
  CHECK_EQ(GridOffsetNs(9803922, 0.3), 2941177u);
  CHECK_EQ(EffectivePeriodNs(10000000, 0.0), 10000000u);
  CHECK_EQ(GridOffsetNs(10000000, 0.0), 0u);
  {
    SampleClock c;
    Oscillator o;
    o.ppm = 20000;
    o.phase = 0.3;
    c.set_oscillator(o);
    c.Start(0, 10000000);
    CHECK_EQ(c.nominal_period_ns(), 10000000u);
    CHECK_EQ(c.period_ns(), 9803922u);
    CHECK_EQ(c.offset_ns(), 2941177u);
    uint64_t t = 0;
    CHECK_EQ(c.Advance(2941176, &t), 0u);  // nothing before O
    CHECK_EQ(c.Advance(2941177, &t), 1u);
    CHECK_EQ(t, 2941177u);
    CHECK_EQ(c.Advance(2941177 + 9803921, &t), 0u);
    CHECK_EQ(c.Advance(2941177 + 9803922, &t), 1u);
    CHECK_EQ(t, 2941177u + 9803922u);
    // 1000 s in uneven steps: every instant O + j P, counted once; 102000 where the ideal part
    // makes 100000.
    uint64_t total = 2, now = 2941177 + 9803922;
    bool ok = true;
    while (now < 1000000000000ull) {
      now += 7777777;
      if (now > 1000000000000ull) now = 1000000000000ull;
      total += c.Advance(now, &t);
      ok = ok && t == 2941177u + (now - 2941177u) / 9803922u * 9803922u;
    }
    CHECK(ok);
    CHECK_EQ(total, 102000u);
  }
  // -12000 ppm (slow), phase 0.25, 800 Hz: P = 1265182 ns, O = 316296 ns; started mid-grid.
  {
    SampleClock c;
    Oscillator o;
    o.ppm = -12000;
    o.phase = 0.25;
    c.set_oscillator(o);
    c.Start(5000000, 1250000);  // instants so far: O + 3 P = 4111842 ns; next O + 4 P
    CHECK_EQ(c.period_ns(), 1265182u);
    CHECK_EQ(c.offset_ns(), 316296u);
    uint64_t t = 0;
    CHECK_EQ(c.Advance(5377023, &t), 0u);
    CHECK_EQ(c.Advance(5377024, &t), 1u);
    CHECK_EQ(t, 5377024u);
    CHECK_EQ(c.Advance(100000000000ull, &t), 79040u - 5u);  // j = 5 .. 79039 by 100 s
    CHECK_EQ(t, 316296u + 79039ull * 1265182u);
    // A new oscillator on a running clock: restarted now on the ideal grid.
    c.set_oscillator(Oscillator());
    c.Restart(100000000001ull);
    CHECK_EQ(c.period_ns(), 1250000u);
    CHECK_EQ(c.offset_ns(), 0u);
    CHECK_EQ(c.Advance(100001250000ull - 1, &t), 0u);
    CHECK_EQ(c.Advance(100001250000ull, &t), 1u);
    CHECK_EQ(t, 100001250000ull);
    c.Stop();
    c.Restart(100002000000ull);  // a stopped clock stays stopped
    CHECK(!c.running());
  }
}

// Parts on their own clocks: a phase makes a later conversion current at the same read time; a
// frequency error scales every period; a running clock takes a new oscillator at once; the
// BNO055's three clocks follow its one oscillator.
void TestPartClocks() {
  Bus bus;
  MotionTrack ramp;  // x: 40 m/s^2 per second
  const double r0[3] = {0, 0, kG}, r1[3] = {40, 0, kG};
  CHECK(ramp.Append(0.0, r0, nullptr));
  CHECK(ramp.Append(1.0, r1, nullptr));
  Adxl345 a(0x53, &ramp), b(0x1D, &ramp);
  CHECK(bus.Attach(&a));
  CHECK(bus.Attach(&b));
  Oscillator half;
  half.phase = 0.5;
  b.set_oscillator(half);  // before measuring: used at the start
  CHECK_EQ(b.oscillator().phase, 0.5);
  for (uint8_t addr : {uint8_t{0x53}, uint8_t{0x1D}}) {  // 100 Hz, full resolution +-2 g
    CHECK(WriteReg(bus, addr, Adxl345::kRegDataFormat, 0x08) == I2cResult::kOk);
    CHECK(WriteReg(bus, addr, Adxl345::kRegPowerCtl, 0x08) == I2cResult::kOk);
  }
  bus.SetTimeNs(57 * kMs);
  CHECK_EQ(a.counters().samples, 5u);  // 10 .. 50 ms
  CHECK_EQ(b.counters().samples, 6u);  // 5 .. 55 ms
  const double lsb = 0.0039 * kG;
  CHECK_EQ(a.counts(0), ToCounts(0.050 * 40, lsb, -512, 511));
  CHECK_EQ(b.counts(0), ToCounts(0.055 * 40, lsb, -512, 511));
  CHECK(b.counts(0) > a.counts(0));
  uint8_t d[6], e[6];
  CHECK(ReadRegs(bus, 0x53, Adxl345::kRegDataX0, d, 6) == I2cResult::kOk);
  CHECK(ReadRegs(bus, 0x1D, Adxl345::kRegDataX0, e, 6) == I2cResult::kOk);
  CHECK(Le16(e) > Le16(d));
  // A new oscillator while converting: a restarts at 57 ms on the grid 5 + 10 j ms.
  a.set_oscillator(half);
  bus.SetTimeNs(65 * kMs - 1);
  CHECK_EQ(a.counters().samples, 5u);  // no conversion at 60 ms
  bus.SetTimeNs(65 * kMs);
  CHECK_EQ(a.counters().samples, 6u);
  CHECK_EQ(a.counts(0), b.counts(0));  // in step now

  // ADXL357 at +20000 ppm, 1000 Hz: P = 980392 ns; 1 s makes 1020 conversions.
  Bus bus2;
  Adxl357 c(0x1D, &ramp);
  CHECK(bus2.Attach(&c));
  Oscillator fast;
  fast.ppm = 20000;
  c.set_oscillator(fast);
  CHECK(WriteReg(bus2, 0x1D, Adxl357::kRegFilter, 0x02) == I2cResult::kOk);
  CHECK(WriteReg(bus2, 0x1D, Adxl357::kRegPowerCtl, 0x00) == I2cResult::kOk);
  CHECK_EQ(c.period_ns(), 980392u);
  bus2.SetTimeNs(1000 * kMs);
  CHECK_EQ(c.counters().samples, 1020u);  // floor(1e9 / 980392)

  // BNO055 at -12000 ppm, phase 0.25: accelerometer (125 Hz), gyroscope (100 Hz) and fusion
  // (100 Hz) all run slow by the same factor on their own phased grids.
  Bus bus3;
  ConstantMotion still(0, 0, kG);
  Bno055 n(0x28, &still);
  CHECK(bus3.Attach(&n));
  CHECK_EQ(n.fusion_period_ns(), 10000000u);
  Oscillator slow;
  slow.ppm = -12000;
  slow.phase = 0.25;
  n.set_oscillator(slow);
  CHECK_EQ(n.fusion_period_ns(), 10121457u);  // the running fusion clock took it at once
  bus3.SetTimeNs(100 * kMs);
  CHECK(WriteReg(bus3, 0x28, Bno055::kRegOprMode, Bno055::kModeAmg) == I2cResult::kOk);
  bus3.SetTimeNs(107 * kMs);  // switched: accel grid 2024292 + 8097166 j ns
  CHECK_EQ(n.accel_period_ns(), 8097166u);
  CHECK_EQ(n.gyro_period_ns(), 10121457u);
  bus3.SetTimeNs(107287450 - 1);
  CHECK_EQ(n.counters().samples, 0u);
  bus3.SetTimeNs(107287450);
  CHECK_EQ(n.counters().samples, 1u);
  bus3.SetTimeNs(115384616 - 1);
  CHECK_EQ(n.counters().samples, 1u);
  bus3.SetTimeNs(115384616);
  CHECK_EQ(n.counters().samples, 2u);
  n.PowerOnReset();  // the oscillator is the part's: a reset keeps it
  CHECK_EQ(n.fusion_period_ns(), 10121457u);
}

// ja_sim_set_clock and the rig spec's clock= field.
void TestCAbiClock() {
  CHECK_EQ(ja_sim_set_clock(nullptr, 0, 0, 0), JA_SIM_EINVAL);
  ja_sim* sim = ja_sim_create();
  CHECK_EQ(ja_sim_set_clock(sim, 0, 0, 0), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("device 0 does not exist") != std::string::npos);
  // Malformed clock fields: the line and the field are named, nothing is attached.
  const char* const bad[] = {
      "a.0 adxl345 0x53 0 clock=1\n",         "\na.0 adxl345 0x53 0 clock=x:0\n",
      "a.0 adxl345 0x53 0 clk=1:0\n",         "a.0 adxl345 0x53 0 clock=1:0:0\n",
      "a.0 adxl345 0x53 0 clock=:0.5\n",      "a.0 adxl345 0x53 0 clock=100000:0\n",
      "a.0 adxl345 0x53 0 clock=-100000:0\n", "a.0 adxl345 0x53 0 clock=0:1\n",
      "a.0 adxl345 0x53 0 clock=0:-0.1\n",    "a.0 adxl345 0x53 0 clock=nan:0\n",
      "a.0 adxl345 0x53 0 clock=0:0 x\n",
  };
  for (const char* spec : bad) {
    CHECK_EQ(ja_sim_attach_rig(sim, spec), JA_SIM_EINVAL);
    const std::string why = ja_sim_last_error(sim);
    const bool named = why.find(spec[0] == '\n' ? "line 2" : "line 1") != std::string::npos &&
                       (why.find("clock") != std::string::npos);
    if (!CHECK(named)) fprintf(stderr, "  %s-> %s\n", spec, why.c_str());
  }
  CHECK(std::string(ja_sim_last_error(sim)).find("expected") != std::string::npos);  // 6 fields
  CHECK_EQ(ja_sim_attach_rig(sim, "a.0 adxl345 0x53 0 clock=100000:0\n"), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("ppm") != std::string::npos);
  CHECK_EQ(ja_sim_attach_rig(sim, "a.0 adxl345 0x53 0 clock=0:1\n"), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("phase") != std::string::npos);
  CHECK_EQ(ja_sim_device_count(sim), 0);

  CHECK_EQ(ja_sim_attach_rig(sim,
                             "mux 0x70\na.0 adxl345 0x53 0 clock=0:0.5\na.1 adxl345 0x53 1\n"
                             "b.0 bno055 0x28 -1 clock=-12000:0.25\n"),
           3);
  CHECK_EQ(ja_sim_set_clock(sim, 0, 0, 0), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("multiplexer") != std::string::npos);
  const int a1 = ja_sim_find_device(sim, "a.1");
  const double nan = std::nan(""), inf = HUGE_VAL;
  const double wrong[][2] = {{nan, 0},     {0, nan}, {inf, 0},  {100000, 0},
                             {-100000, 0}, {0, 1.0}, {0, -0.1}, {0, inf}};
  for (const auto& w : wrong) CHECK_EQ(ja_sim_set_clock(sim, a1, w[0], w[1]), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("clock ppm") != std::string::npos);
  CHECK_EQ(ja_sim_set_clock(sim, a1, 0, -0.1), JA_SIM_EINVAL);
  CHECK(std::string(ja_sim_last_error(sim)).find("phase") != std::string::npos);
  CHECK_EQ(ja_sim_set_clock(sim, a1, 99999.9, 0.999), JA_SIM_OK);
  CHECK_EQ(ja_sim_set_clock(sim, a1, 0, 0), JA_SIM_OK);
  CHECK_EQ(ja_sim_set_clock(sim, ja_sim_find_device(sim, "b.0"), 100, 0.5), JA_SIM_OK);

  // a.0 (phase 0.5) and a.1 (ideal) on one ramp, started together at 100 Hz: at 57 ms a.0 holds
  // the conversion of 55 ms, a.1 the one of 50 ms.
  const double ts[2] = {0.0, 1.0}, acc[6] = {0, 0, kG, 40, 0, kG};
  CHECK_EQ(ja_sim_set_motion(sim, "a.0", 2, ts, acc, nullptr), 1);
  CHECK_EQ(ja_sim_set_motion(sim, "a.1", 2, ts, acc, nullptr), 2);
  const uint8_t both[1] = {0x03}, ch0[1] = {0x01}, ch1[1] = {0x02};
  const uint8_t format[2] = {0x31, 0x08}, measure[2] = {0x2D, 0x08};
  CHECK_EQ(ja_sim_i2c_write(sim, 0x70, both, 1), JA_SIM_OK);
  CHECK_EQ(ja_sim_i2c_write(sim, 0x53, format, 2), JA_SIM_OK);
  CHECK_EQ(ja_sim_i2c_write(sim, 0x53, measure, 2), JA_SIM_OK);
  CHECK_EQ(ja_sim_set_time_us(sim, 57000), JA_SIM_OK);
  ja_sim_device_counters c0, c1;
  CHECK_EQ(ja_sim_get_device_counters(sim, ja_sim_find_device(sim, "a.0"), &c0, sizeof c0),
           JA_SIM_OK);
  CHECK_EQ(ja_sim_get_device_counters(sim, a1, &c1, sizeof c1), JA_SIM_OK);
  CHECK_EQ(c0.samples, 6u);
  CHECK_EQ(c1.samples, 5u);
  const uint8_t reg = 0x32;
  uint8_t x0[2], x1[2];
  CHECK_EQ(ja_sim_i2c_write(sim, 0x70, ch0, 1), JA_SIM_OK);
  CHECK_EQ(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, x0, 2), JA_SIM_OK);
  CHECK_EQ(ja_sim_i2c_write(sim, 0x70, ch1, 1), JA_SIM_OK);
  CHECK_EQ(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, x1, 2), JA_SIM_OK);
  const double lsb = 0.0039 * kG;
  CHECK_EQ(Le16(x0), ToCounts(0.055 * 40, lsb, -512, 511));
  CHECK_EQ(Le16(x1), ToCounts(0.050 * 40, lsb, -512, 511));
  // ja_sim_set_clock on the running a.1: restarted at 57 ms on the grid 5 + 10 j ms.
  CHECK_EQ(ja_sim_set_clock(sim, a1, 0, 0.5), JA_SIM_OK);
  CHECK_EQ(ja_sim_set_time_us(sim, 64999), JA_SIM_OK);
  CHECK_EQ(ja_sim_get_device_counters(sim, a1, &c1, sizeof c1), JA_SIM_OK);
  CHECK_EQ(c1.samples, 5u);
  CHECK_EQ(ja_sim_set_time_us(sim, 65000), JA_SIM_OK);
  CHECK_EQ(ja_sim_get_device_counters(sim, a1, &c1, sizeof c1), JA_SIM_OK);
  CHECK_EQ(c1.samples, 6u);
  ja_sim_destroy(sim);
}

// The rig TOML's simulation-only sim_clock_ppm / sim_clock_phase: to the attach spec's clock=,
// never to the firmware's configuration; out of range named by sensor and field.
void TestRigTomlClock() {
  auto rig = [](const std::string& extra) {
    return "sample_rate_hz = 100\n[links.a]\njoint = [0.3, 0.0]\n[[links.a.sensors]]\n"
           "model = \"adxl345\"\nposition = [0.25, 0.0]\nmux_channel = 0\naddress = 0x53\n" +
           extra +
           "[links.b]\njoint = [0.0, 0.0]\n[[links.b.sensors]]\nmodel = \"adxl345\"\n"
           "position = [0.05, 0.0]\nmux_channel = 1\n";
  };
  ja::app::Config plain, clocked;
  memset(&plain, 0, sizeof plain);
  memset(&clocked, 0, sizeof clocked);
  std::string spec, error;
  CHECK(ja::posix::RigToConfig(rig(""), &plain, &spec, &error));
  CHECK_EQ(spec, std::string("a.0 adxl345 0x53 0\nb.0 adxl345 0x53 1\n"));
  CHECK(ja::posix::RigToConfig(rig("sim_clock_ppm = -12000\nsim_clock_phase = 0.25\n"), &clocked,
                               &spec, &error));
  CHECK_EQ(spec, std::string("a.0 adxl345 0x53 0 clock=-12000:0.25\nb.0 adxl345 0x53 1\n"));
  CHECK(memcmp(&plain, &clocked, sizeof plain) == 0);  // the firmware does not see them
  ja_sim* sim = ja_sim_create();
  CHECK_EQ(ja_sim_attach_rig(sim, spec.c_str()), 2);
  ja_sim_destroy(sim);
  CHECK(ja::posix::RigToConfig(rig("sim_clock_phase = 0.5\n"), &clocked, &spec, &error));
  CHECK_EQ(spec, std::string("a.0 adxl345 0x53 0 clock=0:0.5\nb.0 adxl345 0x53 1\n"));
  // Every digit survives (%.17g).
  CHECK(
      ja::posix::RigToConfig(rig("sim_clock_ppm = 12.345678901234567\n"), &clocked, &spec, &error));
  const size_t eq = spec.find("clock=");
  CHECK(eq != std::string::npos);
  if (eq != std::string::npos) CHECK_EQ(strtod(spec.c_str() + eq + 6, nullptr), 12.345678901234567);
  const char* const bad[][2] = {
      {"sim_clock_ppm = 100000\n", "sim_clock_ppm"},
      {"sim_clock_ppm = -1e6\n", "sim_clock_ppm"},
      {"sim_clock_ppm = nan\n", "sim_clock_ppm"},
      {"sim_clock_phase = 1.0\n", "sim_clock_phase"},
      {"sim_clock_phase = -0.1\n", "sim_clock_phase"},
      {"sim_clock_phase = \"half\"\n", "sim_clock_phase"},
  };
  for (const auto& b : bad) {
    CHECK(!ja::posix::RigToConfig(rig(b[0]), &clocked, &spec, &error));
    const bool named = error.find("links.a.sensors[0]") != std::string::npos &&
                       error.find(b[1]) != std::string::npos;
    if (!CHECK(named)) fprintf(stderr, "  %s-> %s\n", b[0], error.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir = argc > 1 ? argv[1] : ".";
  TestBusStateMachine();
  TestMux();
  TestAdxl345();
  TestAdxl357();
  TestBno055();
  TestFaults();
  TestMotion(dir);
  TestCAbi(dir);
  TestSampleClock();
  TestPartClocks();
  TestCAbiClock();
  TestRigTomlClock();
  return ja_test::Finish("test_sim_devices");
}
