// The virtual I2C bus (master side): byte-level events in, delivered to every device that is
// electrically connected - devices on the root segment always, devices behind a TCA9548A only
// while their channel is connected (multiplexers may be nested). Several devices answering the
// same address wire-AND their bytes, as open-drain outputs do.
//
// Time: the harness sets device time (SetTimeNs/SetTimeUs, never backwards). Optionally the bus
// charges every bit it clocks at `scl_hz` to device time, so a fast-as-possible caller still
// sees transactions take their real duration.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "sim/devices/i2c_target.hpp"
#include "sim/devices/tca9548a.hpp"

namespace ja {
namespace sim {

/// Outcome of a whole transaction (convenience layer).
enum class I2cResult : uint8_t {
  kOk = 0,
  kAddressNack = 1,  // nobody acknowledged the address
  kDataNack = 2,     // a written byte was not acknowledged
  kBusError = 3,     // illegal sequence (e.g. data without START)
};

struct BusCounters {
  uint64_t starts;  // START conditions (from idle)
  uint64_t repeated_starts;
  uint64_t stops;
  uint64_t address_acks;
  uint64_t address_nacks;
  uint64_t data_nacks;     // written bytes not acknowledged
  uint64_t bytes_written;  // data bytes (address bytes excluded)
  uint64_t bytes_read;
  uint64_t bus_errors;  // bytes outside a transaction, reads in write mode, ...
  uint64_t scl_bits;    // SCL periods: 9 per byte (address included), 1 per START/Sr/STOP
};

class Bus {
 public:
  static constexpr int kMaxDevices = 32;

  /// Attaches `dev` (not owned) to the root segment (mux == nullptr) or to `channel` of `mux`,
  /// which must already be attached. False when full, on a bad channel or an unknown mux.
  bool Attach(I2cTarget* dev, const Tca9548a* mux = nullptr, uint8_t channel = 0);
  int device_count() const { return count_; }
  I2cTarget* device(int i) const { return (i >= 0 && i < count_) ? entries_[i].dev : nullptr; }
  /// Whether device i is electrically connected to the master right now.
  bool Reachable(int i) const;

  // ---- Time. ----
  /// Moves device time forward to t (ignored if earlier than now); false if it was earlier.
  bool SetTimeNs(uint64_t t_ns);
  bool SetTimeUs(uint64_t t_us) { return SetTimeNs(t_us * 1000u); }
  uint64_t time_ns() const { return now_ns_; }
  /// 0 (default): bus time is not charged; else each SCL period advances device time.
  void set_scl_hz(uint32_t hz) { scl_hz_ = hz; }
  uint32_t scl_hz() const { return scl_hz_; }

  // ---- Byte level (what simavr's TWI delivers). ----
  void Start();  // START, or repeated START inside a transaction
  /// The first byte after a START is the address byte (addr7 << 1 | R/W). Returns the ACK.
  bool WriteByte(uint8_t byte);
  /// Reads one byte from the addressed device(s); `ack` is the master's answer to it.
  uint8_t ReadByte(bool ack);
  void Stop();
  bool in_transaction() const { return state_ != State::kIdle; }

  // ---- Transactions. ----
  I2cResult Write(uint8_t addr7, const uint8_t* data, size_t n);
  I2cResult Read(uint8_t addr7, uint8_t* data, size_t n);
  /// Write `nw` bytes, repeated START, read `nr` bytes, STOP (smbus2 i2c_rdwr, register reads).
  /// nr = 0 makes it a plain write; nw = nr = 0 an address probe (SLA+R, STOP).
  I2cResult WriteRead(uint8_t addr7, const uint8_t* w, size_t nw, uint8_t* r, size_t nr);

  const BusCounters& counters() const { return counters_; }

 private:
  enum class State : uint8_t { kIdle, kAddress, kWrite, kRead, kNacked };
  struct Entry {
    I2cTarget* dev;
    const Tca9548a* mux;
    uint8_t channel;
  };
  int IndexOf(const I2cTarget* dev) const;
  void Charge(uint32_t bits);
  I2cResult Address(uint8_t addr7, bool read);

  Entry entries_[kMaxDevices] = {};
  bool on_bus_[kMaxDevices] = {};  // connected at the last START
  int count_ = 0;
  State state_ = State::kIdle;
  uint64_t now_ns_ = 0;
  uint64_t bit_rem_ = 0;  // sub-ns remainder of charged bus time, in ns * scl_hz
  uint32_t scl_hz_ = 0;
  BusCounters counters_{};
};

}  // namespace sim
}  // namespace ja
