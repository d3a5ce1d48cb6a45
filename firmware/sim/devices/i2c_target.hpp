// A device on the virtual I2C bus, modelled at byte level (issue 5 item 1): it sees START,
// its address + R/W (ACK or NACK), data bytes with their ACK, repeated START and STOP. The Bus
// delivers every transaction to every reachable device; each filters on its own address.
//
// Device time comes from the harness (SetTimeNs): a real-time board, a fast test and simavr all
// drive the same models. Portable C++14, no OS, no allocation.
#pragma once

#include <stdint.h>

namespace ja {
namespace sim {

/// Injectable per-device faults (docs/design.md §6).
enum class FaultKind : uint8_t {
  kNack = 1,      // param 0: refuse the address; 1: ACK the address, NACK written bytes;
                  // N >= 2: refuse one address phase in every N (intermittent)
  kWrongId = 2,   // ID registers read `param` (0: the bitwise complement of the true ID);
                  // multiplexer: the control register reads back XOR (param ? param : 0xFF)
  kSaturate = 3,  // outputs pinned at the rail with the sign of the input; param = axis mask
                  // (bit0 x, bit1 y, bit2 z; 0 = all)
  kFrozen = 4,    // param 0: outputs stop changing, data-ready keeps coming; param 1: the
                  // conversions stop (no data-ready); multiplexer: control register ignores writes
};
constexpr uint8_t kFaultKindCount = 5;  // valid kinds are 1..4

/// What one device saw and did; all monotonic.
struct DeviceCounters {
  uint64_t transactions;       // address phases ACKed (START/Sr + own address)
  uint64_t address_nacks;      // own address refused (fault, reset in progress)
  uint64_t bytes_written;      // data bytes received, register pointer included
  uint64_t bytes_read;         // data bytes sent
  uint64_t samples;            // conversions made
  uint64_t samples_read;       // conversions whose data registers were read at least once
  uint64_t overruns;           // conversions replaced before they were read
  uint64_t writes_ignored;     // writes to read-only registers or refused in the current mode
  uint64_t config_violations;  // accepted writes the datasheet forbids in the current mode
};

class I2cTarget {
 public:
  explicit I2cTarget(uint8_t addr7) : addr7_(addr7) {}
  virtual ~I2cTarget() = default;
  I2cTarget(const I2cTarget&) = delete;
  I2cTarget& operator=(const I2cTarget&) = delete;

  uint8_t address() const { return addr7_; }
  virtual const char* model() const = 0;

  // ---- Bus side (called by Bus, in bus order). ----
  /// START or repeated START on a segment this device is connected to.
  void BusStart();
  /// The address byte; returns this device's ACK (false if not addressed or refusing).
  bool BusAddress(uint8_t addr7, bool read);
  /// A data byte written by the master while this device is addressed for write; returns ACK.
  bool BusWrite(uint8_t byte);
  /// The next byte this device drives while addressed for read; `master_ack` is what the master
  /// answers after it (false = NACK: last byte, the device releases the bus).
  uint8_t BusRead(bool master_ack);
  /// STOP: the transaction ends.
  void BusStop();
  /// Device time moves to `t_ns` (never backwards). Conversions due by then are made, except
  /// while the device is addressed: its registers stay latched until STOP (multi-byte reads
  /// are coherent, as the parts guarantee).
  void AdvanceTo(uint64_t t_ns);

  // ---- Harness side. ----
  /// Power-on reset: every register to its power-up value (faults and counters are kept).
  virtual void PowerOnReset() = 0;
  virtual bool SupportsFault(FaultKind kind) const;
  /// Sets or clears a fault; false if this device does not model that fault.
  bool SetFault(FaultKind kind, bool on, uint32_t param = 0);
  void ClearFaults() { faults_ = 0; }
  bool fault(FaultKind kind) const { return (faults_ >> static_cast<uint8_t>(kind)) & 1u; }
  uint32_t fault_param(FaultKind kind) const { return fault_param_[static_cast<uint8_t>(kind)]; }
  const DeviceCounters& counters() const { return counters_; }
  uint64_t now_ns() const { return now_ns_; }
  bool addressed() const { return phase_ == Phase::kWrite || phase_ == Phase::kRead; }

 protected:
  /// Device-specific refusal of its own address (e.g. booting). Default: ACK.
  virtual bool AcceptAddress(bool /*read*/) { return true; }
  /// The address was acknowledged: a write or a read phase begins.
  virtual void OnAddressed(bool /*read*/) {}
  /// A written data byte; `first` is the first byte after the address (the register pointer
  /// of register-mapped parts). Returns ACK.
  virtual bool OnWrite(uint8_t byte, bool first) = 0;
  virtual uint8_t OnRead() = 0;
  /// The transaction this device took part in has ended (STOP).
  virtual void OnStop() {}
  /// Make the conversions due at now_ns() (never called while addressed).
  virtual void Update() {}
  /// The kFrozen fault with param 1: the conversions stop.
  bool conversions_stopped() const {
    return fault(FaultKind::kFrozen) && fault_param(FaultKind::kFrozen) == 1;
  }
  /// Counts n >= 1 new conversions: each replaces the previous one, an overrun unless that one
  /// had been read (*unread clear); the newest is unread.
  void CountConversions(uint64_t n, bool* unread) {
    counters_.samples += n;
    counters_.overruns += *unread ? n : n - 1;
    *unread = true;
  }

  DeviceCounters counters_{};

 private:
  enum class Phase : uint8_t { kIdle, kWrite, kRead, kReleased };
  uint8_t addr7_;
  Phase phase_ = Phase::kIdle;
  bool first_write_ = false;
  bool latched_ = false;  // addressed since the last STOP: conversions wait
  uint8_t faults_ = 0;    // bit n = FaultKind n
  uint32_t fault_param_[kFaultKindCount] = {};
  uint32_t nack_phase_ = 0;  // address phases seen under an intermittent NACK fault
  uint64_t now_ns_ = 0;
};

/// Parts with a register pointer (ADXL345, ADXL357, BNO055): the first written byte sets the
/// pointer, later bytes write registers with auto-increment, reads auto-increment from it.
/// The pointer survives a repeated START (combined write-read).
class RegisterDevice : public I2cTarget {
 public:
  using I2cTarget::I2cTarget;
  uint8_t pointer() const { return pointer_; }

 protected:
  void OnAddressed(bool read) override;
  bool OnWrite(uint8_t byte, bool first) override;
  uint8_t OnRead() override;
  /// Whether the pointer stays on `reg` after this read instead of auto-incrementing (a FIFO
  /// port read in a burst). Default: never.
  virtual bool HoldsPointer(uint8_t /*reg*/) const { return false; }
  /// Whether the pointer has auto-incremented since the read phase began: the register now
  /// read was reached from the previous one, not addressed directly.
  bool burst_moved() const { return burst_moved_; }
  /// Register read as the master sees it (may clear flags, e.g. data-ready).
  virtual uint8_t ReadRegister(uint8_t reg) = 0;
  /// Register write; returns false if the byte is to be NACKed.
  virtual bool WriteRegister(uint8_t reg, uint8_t value) = 0;

 private:
  uint8_t pointer_ = 0;
  bool burst_moved_ = false;
};

}  // namespace sim
}  // namespace ja
