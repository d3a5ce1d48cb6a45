#include "sim/devices/i2c_target.hpp"

namespace ja {
namespace sim {

void I2cTarget::BusStart() {
  // A repeated START ends the current phase; the latch (and the register pointer) survive.
  phase_ = Phase::kIdle;
}

bool I2cTarget::BusAddress(uint8_t addr7, bool read) {
  phase_ = Phase::kIdle;
  if (addr7 != addr7_) return false;
  bool refuse = !AcceptAddress(read);
  if (fault(FaultKind::kNack)) {
    const uint32_t p = fault_param(FaultKind::kNack);
    if (p == 0 || (p >= 2 && ++nack_phase_ % p == 0)) refuse = true;
  }
  if (refuse) {
    ++counters_.address_nacks;
    return false;
  }
  ++counters_.transactions;
  latched_ = true;
  phase_ = read ? Phase::kRead : Phase::kWrite;
  first_write_ = true;
  OnAddressed(read);
  return true;
}

bool I2cTarget::BusWrite(uint8_t byte) {
  if (phase_ != Phase::kWrite) return false;
  ++counters_.bytes_written;
  const bool first = first_write_;
  first_write_ = false;
  if (fault(FaultKind::kNack)) return false;  // param 1: data NACK
  return OnWrite(byte, first);
}

uint8_t I2cTarget::BusRead(bool master_ack) {
  if (phase_ != Phase::kRead) return 0xFF;  // not driving: the bus floats high
  ++counters_.bytes_read;
  const uint8_t b = OnRead();
  if (!master_ack) phase_ = Phase::kReleased;
  return b;
}

void I2cTarget::BusStop() {
  const bool was_latched = latched_;
  phase_ = Phase::kIdle;
  latched_ = false;
  if (was_latched) {
    OnStop();
    Update();
  }
}

void I2cTarget::AdvanceTo(uint64_t t_ns) {
  if (t_ns > now_ns_) now_ns_ = t_ns;
  if (!latched_) Update();
}

bool I2cTarget::SupportsFault(FaultKind kind) const {
  return static_cast<uint8_t>(kind) >= 1 && static_cast<uint8_t>(kind) < kFaultKindCount;
}

bool I2cTarget::SetFault(FaultKind kind, bool on, uint32_t param) {
  if (!SupportsFault(kind)) return false;
  const uint8_t k = static_cast<uint8_t>(kind);
  if (on) {
    faults_ = static_cast<uint8_t>(faults_ | (1u << k));
    fault_param_[k] = param;
    if (kind == FaultKind::kNack) nack_phase_ = 0;
  } else {
    faults_ = static_cast<uint8_t>(faults_ & ~(1u << k));
    fault_param_[k] = 0;
  }
  return true;
}

bool RegisterDevice::OnWrite(uint8_t byte, bool first) {
  if (first) {
    pointer_ = byte;
    return true;
  }
  const bool ack = WriteRegister(pointer_, byte);
  pointer_ = static_cast<uint8_t>(pointer_ + 1);
  return ack;
}

void RegisterDevice::OnAddressed(bool /*read*/) { burst_moved_ = false; }

uint8_t RegisterDevice::OnRead() {
  const uint8_t v = ReadRegister(pointer_);
  if (!HoldsPointer(pointer_)) {
    pointer_ = static_cast<uint8_t>(pointer_ + 1);
    burst_moved_ = true;
  }
  return v;
}

}  // namespace sim
}  // namespace ja
