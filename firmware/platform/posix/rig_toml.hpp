// The rig file (docs/design.md §4) read by the native virtual board: a minimal TOML reader for
// the rig contract only (tables, arrays of tables, numbers, strings, booleans, nested arrays of
// numbers, '#' comments, arrays spanning lines), and its translation into the application's
// configuration (app/app_config.hpp) and the virtual devices' attach spec (ja_sim_attach_rig).
#pragma once

#include <string>

#include "app/app_config.hpp"

namespace ja {
namespace posix {

/// Parses `text` into `cfg` (factory defaults first, then the rig: rate, joints, sensors links a
/// then b in file order, optional S and offset as calibration) and writes the virtual devices'
/// spec ("a.0 adxl345 0x53 0" lines) into `sim_spec`. A sensor's simulation-only
/// `sim_clock_ppm` and `sim_clock_phase` (|ppm| < 100000, 0 <= phase < 1; default 0) go to the
/// spec only (" clock=<ppm>:<phase>" when not both 0), never to `cfg`; other keys, the host's
/// other `sim_*` ones included, are ignored. False with `error` set on any problem.
bool RigToConfig(const std::string& text, app::Config* cfg, std::string* sim_spec,
                 std::string* error);

}  // namespace posix
}  // namespace ja
