// Small in-test fakes for the application tests: a register-level I2C bus with a TCA9548A and
// simple ADXL345 / ADXL357 / BNO055 models (not the full virtual devices of firmware/sim), a
// manual microsecond clock, a UART with a bounded transmit buffer, an EEPROM array and a reboot
// flag. Everything is fixed-size (no allocation), so the same fakes serve test_app_no_alloc.
#pragma once

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "app/app.hpp"
#include "protocol/frame.hpp"
#include "protocol/messages.hpp"

namespace ja_test {

namespace proto = ja::proto;
using ja::drivers::I2cStatus;

class FakeClock final : public ja::app::Clock {
 public:
  uint32_t NowUs() override { return now_us; }
  uint32_t now_us = 1000;  // not 0: the app must not depend on a zero start
};

class FakeDelay final : public ja::drivers::Delay {
 public:
  explicit FakeDelay(FakeClock& c) : clock_(c) {}
  void WaitMs(uint16_t ms) override {
    clock_.now_us += 1000u * ms;
    total_ms += ms;
  }
  uint32_t total_ms = 0;

 private:
  FakeClock& clock_;
};

/// One simulated chip: a register file and a specific force in its own frame.
struct FakeChip {
  uint8_t model = 0;  // proto::SensorModel
  uint8_t address = 0;
  int channel = -1;  // TCA9548A channel, -1 = on the bus directly
  uint8_t regs[256] = {};
  uint8_t regs1[256] = {};  // BNO055 page 1
  uint8_t page = 0;
  float force_mps2[3] = {0, 0, 0};
  // Faults.
  bool nack = false;
  uint32_t nack_next = 0;  // NACK this many more transactions, then answer again
  bool frozen = false;     // data registers stop changing (DATA_READY still set)
  bool saturate = false;   // every axis at its positive full scale
  uint32_t reads = 0;

  void Reset() {
    memset(regs, 0, sizeof regs);
    memset(regs1, 0, sizeof regs1);
    page = 0;
    switch (static_cast<proto::SensorModel>(model)) {
      case proto::SensorModel::kAdxl345:
        regs[0x00] = 0xE5;
        regs[0x2C] = 0x0A;
        break;
      case proto::SensorModel::kAdxl357:
        regs[0x00] = 0xAD;
        regs[0x01] = 0x1D;
        regs[0x02] = 0xED;
        regs[0x2C] = 0x81;
        regs[0x2D] = 0x01;
        break;
      case proto::SensorModel::kBno055:
        regs[0x00] = 0xA0;
        regs1[0x08] = 0x0D;
        break;
      default:
        break;
    }
  }

  int32_t Counts(int axis) const {
    // A small deterministic dither so a healthy sensor never looks frozen.
    const float dither = static_cast<float>(static_cast<int>(reads % 3u) - 1);
    switch (static_cast<proto::SensorModel>(model)) {
      case proto::SensorModel::kAdxl345: {
        const int32_t range_g = 2 << (regs[0x31] & 3);
        const int32_t lim = 256 * range_g - 1;
        if (saturate) return lim;
        int32_t c = static_cast<int32_t>(lroundf(force_mps2[axis] / (0.0039f * 9.80665f) + dither));
        return c > lim ? lim : c < -lim - 1 ? -lim - 1 : c;
      }
      case proto::SensorModel::kAdxl357: {
        const float lsb_per_g = 51200.0f / static_cast<float>(1 << ((regs[0x2C] & 3) - 1));
        if (saturate) return 524287;
        return static_cast<int32_t>(lroundf(force_mps2[axis] / 9.80665f * lsb_per_g + dither));
      }
      case proto::SensorModel::kBno055:
        if (saturate) return 32767;
        return static_cast<int32_t>(lroundf(force_mps2[axis] * 100.0f + dither));
      default:
        return 0;
    }
  }

  /// In its measuring mode, as configured by the driver: a chip in standby (ADXL345, ADXL357)
  /// or in CONFIG mode (BNO055) converts nothing, as after a reset of its own.
  bool Measuring() const {
    switch (static_cast<proto::SensorModel>(model)) {
      case proto::SensorModel::kAdxl345:
        return (regs[0x2D] & 0x08) != 0;
      case proto::SensorModel::kAdxl357:
        return (regs[0x2D] & 0x01) == 0;
      case proto::SensorModel::kBno055:
        return (regs[0x3D] & 0x0F) != 0;
      default:
        return false;
    }
  }

  /// Refreshes the data registers (a new conversion), unless frozen or not measuring.
  void Convert() {
    if (frozen || !Measuring()) return;
    ++reads;
    switch (static_cast<proto::SensorModel>(model)) {
      case proto::SensorModel::kAdxl345:
        regs[0x30] |= 0x80;
        for (int a = 0; a < 3; ++a) {
          const uint16_t u = static_cast<uint16_t>(static_cast<int16_t>(Counts(a)));
          regs[0x32 + 2 * a] = static_cast<uint8_t>(u);
          regs[0x33 + 2 * a] = static_cast<uint8_t>(u >> 8);
        }
        break;
      case proto::SensorModel::kAdxl357:
        regs[0x04] |= 0x01;
        for (int a = 0; a < 3; ++a) {
          const uint32_t u = static_cast<uint32_t>(Counts(a)) & 0xFFFFFu;
          regs[0x08 + 3 * a] = static_cast<uint8_t>(u >> 12);
          regs[0x09 + 3 * a] = static_cast<uint8_t>(u >> 4);
          regs[0x0A + 3 * a] = static_cast<uint8_t>((u & 0xF) << 4);
        }
        break;
      case proto::SensorModel::kBno055:
        for (int a = 0; a < 3; ++a) {
          const uint16_t u = static_cast<uint16_t>(static_cast<int16_t>(Counts(a)));
          regs[0x08 + 2 * a] = static_cast<uint8_t>(u);
          regs[0x09 + 2 * a] = static_cast<uint8_t>(u >> 8);
        }
        break;
      default:
        break;
    }
  }
};

/// The bus: a TCA9548A at 0x70 and up to 16 chips. Every transaction can cost simulated time.
class FakeBus final : public ja::drivers::I2cBus {
 public:
  explicit FakeBus(FakeClock& c) : clock_(c) {}

  FakeChip& Add(uint8_t model, uint8_t address, int channel) {
    FakeChip& c = chips[count++];
    c.model = model;
    c.address = address;
    c.channel = channel;
    c.Reset();
    return c;
  }

  I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override {
    ++transactions;
    clock_.now_us += us_per_transaction;
    if (addr7 == kMux) {
      if (mux_nack) return I2cStatus::kNack;
      if (!mux_stuck) mux_control = reg;
      if (n != 0) ++mux_readbacks;
      for (uint8_t i = 0; i < n; ++i) buf[i] = mux_control;
      return I2cStatus::kOk;
    }
    FakeChip* c = Find(addr7);
    if (!c) return I2cStatus::kNack;
    const bool data_read = IsDataRead(*c, reg);
    if (data_read) c->Convert();
    uint8_t* map = (c->model == static_cast<uint8_t>(proto::SensorModel::kBno055) && c->page == 1 &&
                    reg != 0x07)
                       ? c->regs1
                       : c->regs;
    for (uint8_t i = 0; i < n; ++i) buf[i] = map[static_cast<uint8_t>(reg + i)];
    // Reading INT_SOURCE / STATUS clears data-ready (as the chips do when data is read).
    if (data_read && c->model == static_cast<uint8_t>(proto::SensorModel::kAdxl345)) {
      c->regs[0x30] &= 0x7F;
    }
    if (data_read && c->model == static_cast<uint8_t>(proto::SensorModel::kAdxl357)) {
      c->regs[0x04] &= 0xFE;
    }
    return I2cStatus::kOk;
  }

  I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override {
    ++transactions;
    clock_.now_us += us_per_transaction;
    if (addr7 == kMux) {
      if (mux_nack) return I2cStatus::kNack;
      if (!mux_stuck) mux_control = reg;
      ++mux_writes;
      return I2cStatus::kOk;
    }
    FakeChip* c = Find(addr7);
    if (!c) return I2cStatus::kNack;
    for (uint8_t i = 0; i < n; ++i) {
      const uint8_t r = static_cast<uint8_t>(reg + i);
      if (c->model == static_cast<uint8_t>(proto::SensorModel::kBno055) && r == 0x07) {
        c->page = buf[i];
        continue;
      }
      uint8_t* map = (c->model == static_cast<uint8_t>(proto::SensorModel::kBno055) && c->page == 1)
                         ? c->regs1
                         : c->regs;
      map[r] = buf[i];
    }
    return I2cStatus::kOk;
  }

  static constexpr uint8_t kMux = 0x70;
  FakeChip chips[16];
  int count = 0;
  uint8_t mux_control = 0;
  bool mux_nack = false;
  bool mux_stuck = false;  // ACKs every select but keeps its channel (a read-back shows it)
  uint32_t mux_readbacks = 0, mux_writes = 0;  // selects read back / written without read-back
  uint32_t us_per_transaction = 0;
  uint32_t transactions = 0;

 private:
  static bool IsDataRead(const FakeChip& c, uint8_t reg) {
    switch (static_cast<proto::SensorModel>(c.model)) {
      case proto::SensorModel::kAdxl345:
        return reg == 0x30 || reg == 0x32;  // INT_SOURCE..DATAZ1 or DATAX0..DATAZ1
      case proto::SensorModel::kAdxl357:
        return reg == 0x04 || reg == 0x08;  // STATUS..ZDATA1 or XDATA3..ZDATA1
      case proto::SensorModel::kBno055:
        return reg == 0x08 && c.page == 0;
      default:
        return false;
    }
  }
  FakeChip* Find(uint8_t addr7) {
    for (int i = 0; i < count; ++i) {
      FakeChip& c = chips[i];
      if (c.address != addr7) continue;
      if (c.channel >= 0 && !(mux_control & (1u << c.channel))) continue;
      if (c.nack_next > 0) {
        --c.nack_next;
        return nullptr;
      }
      return c.nack ? nullptr : &c;
    }
    return nullptr;
  }
  FakeClock& clock_;
};

/// UART: a bounded transmit buffer (capacity bytes) that the test drains; a receive queue.
class FakeSerial final : public ja::app::SerialPort {
 public:
  static constexpr uint32_t kBuffer = 8192;
  uint16_t TxFree() override { return static_cast<uint16_t>(capacity - tx_len); }
  void TxWrite(const uint8_t* d, uint16_t n) override {
    if (tx_len + n > capacity) {
      overflow_writes++;  // the app must never write more than TxFree()
      return;
    }
    memcpy(tx + tx_len, d, n);
    tx_len += n;
  }
  int16_t RxRead() override {
    if (rx_head == rx_len) return -1;
    return rx[rx_head++];
  }
  void Inject(const uint8_t* d, size_t n) {
    if (rx_head == rx_len) rx_head = rx_len = 0;
    memcpy(rx + rx_len, d, n);
    rx_len += static_cast<uint32_t>(n);
  }
  /// Takes up to max bytes out of the transmit buffer (what the line carried meanwhile).
  template <class F>
  uint32_t Drain(uint32_t max, F&& sink) {
    const uint32_t n = max < tx_len ? max : tx_len;
    for (uint32_t i = 0; i < n; ++i) sink(tx[i]);
    memmove(tx, tx + n, tx_len - n);
    tx_len -= n;
    return n;
  }

  uint32_t capacity = 1024;
  uint8_t tx[kBuffer];
  uint32_t tx_len = 0;
  uint8_t rx[kBuffer];
  uint32_t rx_head = 0, rx_len = 0;
  uint32_t overflow_writes = 0;
};

class FakeEeprom final : public ja::app::Eeprom {
 public:
  FakeEeprom() {
    memset(bytes, 0xFF, sizeof bytes);
    memset(pending, 0xFF, sizeof pending);
  }
  uint16_t Size() override { return sizeof bytes; }
  uint8_t Read(uint16_t a) override { return bytes[a]; }
  void Write(uint16_t a, uint8_t v) override {
    ++writes;
    if (staged) {
      if (!dirty) memcpy(pending, bytes, sizeof bytes);
      dirty = true;
      pending[a] = v;
    } else if (!broken) {
      bytes[a] = v;
    }
  }
  bool Commit() override {
    ++commits;
    if (dirty && !broken) memcpy(bytes, pending, sizeof bytes);
    dirty = false;
    return !commit_fails;
  }
  uint8_t bytes[4096];
  uint32_t writes = 0;
  uint32_t commits = 0;
  bool broken = false;  // writes are lost (worn-out cell)
  // A store that takes whole sectors (the Pico's flash): writes wait in `pending` until Commit,
  // Read shows what is stored.
  bool staged = false;
  bool commit_fails = false;
  bool dirty = false;
  uint8_t pending[4096];
};

class FakeSystem final : public ja::app::System {
 public:
  void Reboot() override { ++reboots; }
  int reboots = 0;
};

/// The asynchronous batch (app/hal.hpp) over the fake bus: the transfers run when the batch
/// starts (as the AVR's TWI interrupt starts them at once); the app only sees the results after
/// Wait(), one loop later, which is the pipelined path the AVR board takes.
class FakeBatch final : public ja::app::I2cBatch {
 public:
  explicit FakeBatch(ja::drivers::I2cBus& bus) : bus_(bus) {}
  void Start(ja::app::I2cTransfer* t, uint8_t count) override {
    ++starts;
    if (running) ++overlapping;  // a batch started before the previous one was collected
    running = true;
    last_scl = 0;
    for (uint8_t i = 0; i < count; ++i) {
      if (t[i].after != ja::app::I2cTransfer::kNoDependency &&
          t[t[i].after].status != I2cStatus::kOk) {
        t[i].status = I2cStatus::kBusError;
        continue;
      }
      // n = 0: a write of the register byte alone (a multiplexer select without read-back).
      t[i].status = t[i].n == 0 ? bus_.Write(t[i].addr7, t[i].reg, nullptr, 0)
                                : bus_.Read(t[i].addr7, t[i].reg, t[i].buf, t[i].n);
      // Its SCL periods on a real bus: START, 9 a byte written (address, register), STOP; a
      // read adds a repeated START and 9 a byte read (address, data).
      last_scl += 20u + (t[i].n != 0 ? 1u + 9u * (1u + t[i].n) : 0u);
    }
  }
  void Wait() override { running = false; }
  bool running = false;
  uint32_t starts = 0, overlapping = 0;
  uint32_t last_scl = 0;  // SCL periods of the transfers the last batch ran

 private:
  ja::drivers::I2cBus& bus_;
};

/// One decoded frame from the device.
struct Frame {
  proto::FrameHeader header;
  uint8_t payload[proto::kMaxPayload];
  size_t size;
};

/// A whole test board: the fakes, an App over them, and the host side (decoder + frame log).
class Board {
 public:
  Board()
      : bus(clock),
        delay(clock),
        hal{bus, delay, clock, serial, eeprom, system, static_cast<uint8_t>(proto::Board::kNative)},
        batch(bus) {
#ifdef JA_TEST_PIPELINED
    hal.batch = &batch;  // test_app_pipelined: every test again over the asynchronous batch
#endif
  }

  /// The default rig: four ADXL345 at 0x53 on mux channels 0-3 (the app's factory defaults).
  void AddDefaultChips() {
    for (int ch = 0; ch < 4; ++ch)
      bus.Add(static_cast<uint8_t>(proto::SensorModel::kAdxl345), 0x53, ch);
  }

  /// Queues a command frame for the device.
  template <class Msg>
  uint16_t Command(const Msg& m) {
    uint8_t buf[proto::kMaxFrameBytes];
    const uint16_t seq = host_seq++;
    const size_t n = proto::encode_message(m, seq, 0, buf, sizeof buf);
    serial.Inject(buf, n);
    return seq;
  }

  /// Runs the device for `us` of simulated time, the line carrying `line_bytes_per_ms`.
  void Run(ja::app::App& app, uint32_t us) {
    const uint32_t end = clock.now_us + us;
    while (static_cast<int32_t>(end - clock.now_us) > 0) {
      const uint32_t before = clock.now_us;
      uint32_t wait = app.Poll();
      if (system.reboots != handled_reboots) {
        handled_reboots = system.reboots;
        app.Begin();
        continue;
      }
      const uint32_t left = end - clock.now_us;
      if (static_cast<int32_t>(left) <= 0) break;
      if (wait > left) wait = left;
      if (wait == 0 && clock.now_us == before) wait = 1;
      clock.now_us += wait;
      const uint32_t elapsed = clock.now_us - before;
      drain_credit += static_cast<uint64_t>(elapsed) * line_bytes_per_ms;
      const uint32_t can = static_cast<uint32_t>(drain_credit / 1000u);
      drain_credit -=
          static_cast<uint64_t>(serial.Drain(can, [this](uint8_t b) { Receive(b); })) * 1000u;
      if (serial.tx_len == 0) drain_credit = 0;
    }
  }

  /// Everything still in the transmit buffer reaches the host.
  void Flush() {
    serial.Drain(serial.tx_len, [this](uint8_t b) { Receive(b); });
  }

  void Receive(uint8_t b) {
    if (decoder.push(b) != proto::DecodeEvent::kFrame) return;
    if (frame_count >= kMaxFrames) {
      ++frames_overflow;
      return;
    }
    Frame& f = frames[frame_count++];
    f.header = decoder.header();
    f.size = decoder.payload_size();
    memcpy(f.payload, decoder.payload(), f.size);
  }

  /// Decodes the i-th frame of type Msg; false if there is none.
  template <class Msg>
  bool Find(Msg* out, int nth = 0, int from = 0) const {
    for (int i = from; i < frame_count; ++i) {
      if (frames[i].header.msg_id != Msg::kId) continue;
      if (nth-- > 0) continue;
      return out->decode(frames[i].payload, frames[i].size);
    }
    return false;
  }
  template <class Msg>
  bool Last(Msg* out) const {
    for (int i = frame_count - 1; i >= 0; --i) {
      if (frames[i].header.msg_id == Msg::kId)
        return out->decode(frames[i].payload, frames[i].size);
    }
    return false;
  }
  template <class Msg>
  int Count(int from = 0) const {
    int n = 0;
    for (int i = from; i < frame_count; ++i) n += frames[i].header.msg_id == Msg::kId;
    return n;
  }
  /// The ack of the command sent with host seq `seq`; error 255 if none arrived.
  uint8_t AckError(uint8_t id, uint16_t seq) const {
    for (int i = 0; i < frame_count; ++i) {
      if (frames[i].header.msg_id != proto::Ack::kId) continue;
      proto::Ack a;
      if (a.decode(frames[i].payload, frames[i].size) && a.command_id == id &&
          a.command_seq == seq) {
        return a.error;
      }
    }
    return 255;
  }
  void ClearFrames() { frame_count = 0; }

  FakeClock clock;
  FakeBus bus;
  FakeDelay delay;
  FakeSerial serial;
  FakeEeprom eeprom;
  FakeSystem system;
  ja::app::Hal hal;
  FakeBatch batch;
  proto::FrameDecoder decoder;
  static constexpr int kMaxFrames = 4096;
  Frame frames[kMaxFrames];
  int frame_count = 0;
  int frames_overflow = 0;
  uint16_t host_seq = 0;
  uint32_t line_bytes_per_ms = 100;  // 1 Mbaud, 10 bits per byte
  uint64_t drain_credit = 0;
  int handled_reboots = 0;
};

}  // namespace ja_test
