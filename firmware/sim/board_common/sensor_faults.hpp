// Scheduled sensor faults of the virtual boards (ja_native_board, ja_avr_board, ja_sim_board.h;
// the option in
// firmware/platform/posix/README.md):
//   --fault SENSOR:KIND[=PARAM]@START[-END]   (repeatable)
// SENSOR a.0, a.1, b.0, ... (rig order) or mux; KIND nack, wrong_id, saturate, frozen (PARAM:
// firmware/sim/devices/i2c_target.hpp FaultKind); START, END in simulated seconds (no END: until
// the board stops). Switched on and off in the board's simulated time through the ja_sim_devices
// C ABI (ja_sim_inject_fault, ja_sim_clear_fault).
#pragma once

#include <stdint.h>

#include <string>
#include <vector>

#include "sim/devices/ja_sim_devices.h"

namespace ja {
namespace board {

struct SensorFault {
  std::string sensor;  // motion id ("a.0") or "mux"
  int kind = 0;        // JA_SIM_FAULT_*
  uint32_t param = 0;
  uint64_t start_ns = 0, end_ns = ~0ull;  // ~0: never cleared
  int dev = -1;
  bool on = false, done = false;
};

/// Parses one spec; false with *why when malformed.
bool ParseSensorFault(const std::string& text, SensorFault* f, std::string* why);
/// Binds every fault to its device; false with *why naming a sensor the rig does not have.
bool ResolveSensorFaults(ja_sim* sim, std::vector<SensorFault>* faults, std::string* why);
/// Switches faults whose time has come (a line on stderr for each).
void ApplySensorFaults(ja_sim* sim, std::vector<SensorFault>* faults, uint64_t now_ns);

}  // namespace board
}  // namespace ja
