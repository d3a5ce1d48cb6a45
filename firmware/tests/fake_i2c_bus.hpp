// A fake I2C bus for driver tests: devices are register files keyed by 7-bit address, every
// transaction is recorded, and faults can be injected (NACK on an address, ignored writes).
#pragma once

#include <cstdint>
#include <list>
#include <vector>

#include "drivers/i2c_bus.hpp"

namespace ja_test {

struct Transaction {
  bool is_read;
  uint8_t addr7;
  uint8_t reg;
  std::vector<uint8_t> data;  // bytes written, or bytes returned
};

struct FakeDevice {
  uint8_t regs[256] = {};
  bool nack = false;                 // refuses its address
  bool ignore_writes = false;        // ACKs writes but keeps the old values
  bool no_register_pointer = false;  // TCA9548A: `reg` is the control byte, reads return it
  uint8_t page = 0;                  // BNO055-style paged map: page 1 in regs1
  bool paged = false;
  uint8_t regs1[256] = {};
  std::vector<uint8_t> write_log;  // registers written, in order
};

class FakeI2cBus final : public ja::drivers::I2cBus {
 public:
  /// Adds a device; channel >= 0 puts it behind the multiplexer at mux_addr7 (reachable only
  /// while that channel is enabled), so identical parts can share an address.
  FakeDevice& Add(uint8_t addr7, int channel = -1) {
    devices_.push_back(Entry{addr7, channel, FakeDevice{}});
    return devices_.back().device;
  }
  uint8_t mux_addr7 = 0x70;
  std::vector<Transaction> log;

  ja::drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override {
    FakeDevice* d = Find(addr7);
    if (!d) return ja::drivers::I2cStatus::kNack;
    Transaction t{true, addr7, reg, {}};
    if (d->no_register_pointer) {
      if (!d->ignore_writes) d->regs[0] = reg;
      for (uint8_t i = 0; i < n; ++i) buf[i] = d->regs[0];
    } else {
      uint8_t* map = (d->paged && d->page == 1 && reg != 0x07) ? d->regs1 : d->regs;
      for (uint8_t i = 0; i < n; ++i) buf[i] = map[static_cast<uint8_t>(reg + i)];
    }
    t.data.assign(buf, buf + n);
    log.push_back(t);
    return ja::drivers::I2cStatus::kOk;
  }

  ja::drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override {
    FakeDevice* d = Find(addr7);
    if (!d) return ja::drivers::I2cStatus::kNack;
    log.push_back(Transaction{false, addr7, reg, std::vector<uint8_t>(buf, buf + n)});
    if (d->no_register_pointer) {
      if (!d->ignore_writes) d->regs[0] = reg;
      return ja::drivers::I2cStatus::kOk;
    }
    for (uint8_t i = 0; i < n; ++i) {
      const uint8_t r = static_cast<uint8_t>(reg + i);
      d->write_log.push_back(r);
      if (d->ignore_writes) continue;
      if (d->paged && r == 0x07) {
        d->page = buf[i];
        d->regs[r] = buf[i];
        d->regs1[r] = buf[i];
        continue;
      }
      uint8_t* map = (d->paged && d->page == 1) ? d->regs1 : d->regs;
      map[r] = buf[i];
    }
    return ja::drivers::I2cStatus::kOk;
  }

 private:
  struct Entry {
    uint8_t addr7;
    int channel;
    FakeDevice device;
  };
  uint8_t MuxControl() {
    for (Entry& e : devices_) {
      if (e.addr7 == mux_addr7 && e.channel < 0) return e.device.regs[0];
    }
    return 0;
  }
  FakeDevice* Find(uint8_t addr7) {
    const uint8_t control = MuxControl();
    for (Entry& e : devices_) {
      if (e.addr7 != addr7) continue;
      if (e.channel >= 0 && !(control & (1u << e.channel))) continue;
      return e.device.nack ? nullptr : &e.device;
    }
    return nullptr;
  }
  std::list<Entry> devices_;
};

class FakeDelay final : public ja::drivers::Delay {
 public:
  void WaitMs(uint16_t ms) override { waits.push_back(ms); }
  std::vector<uint16_t> waits;
};

}  // namespace ja_test
