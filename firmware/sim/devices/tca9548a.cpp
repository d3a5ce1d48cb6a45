#include "sim/devices/tca9548a.hpp"

namespace ja {
namespace sim {

void Tca9548a::PowerOnReset() {
  control_ = 0;
  connected_ = 0;
}

bool Tca9548a::SupportsFault(FaultKind kind) const {
  return kind == FaultKind::kNack || kind == FaultKind::kWrongId || kind == FaultKind::kFrozen;
}

bool Tca9548a::OnWrite(uint8_t byte, bool /*first*/) {
  if (fault(FaultKind::kFrozen)) {
    ++counters_.writes_ignored;
    return true;  // ACKs, keeps the old selection
  }
  control_ = byte;
  return true;
}

uint8_t Tca9548a::OnRead() {
  if (fault(FaultKind::kWrongId)) {
    const uint32_t p = fault_param(FaultKind::kWrongId);
    return static_cast<uint8_t>(control_ ^ (p ? p : 0xFFu));
  }
  return control_;
}

void Tca9548a::OnStop() { connected_ = control_; }

}  // namespace sim
}  // namespace ja
