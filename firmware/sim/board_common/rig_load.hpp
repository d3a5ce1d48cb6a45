// The rig and the motion every virtual board starts from: --rig RIG.toml as the application's
// configuration (platform/posix/rig_toml.hpp) and as the virtual devices on a new ja_sim, which
// plays --motion (looped with --loop-motion) and knows the --fault sensors.
#pragma once

#include <memory>
#include <string>

#include "app/app_config.hpp"
#include "sim/board_common/options.hpp"
#include "sim/devices/ja_sim_devices.h"

namespace ja {
namespace board {

struct SimDeleter {
  void operator()(ja_sim* s) const { ja_sim_destroy(s); }
};
using SimPtr = std::unique_ptr<ja_sim, SimDeleter>;

/// Reads o->rig into *cfg, attaches its devices to a new ja_sim, loads o->motion and binds
/// o->faults to their devices. Null with *error naming the file or option at fault.
SimPtr LoadRig(CommonOptions* o, app::Config* cfg, std::string* error);
/// The same, the error on stderr after the program's name.
SimPtr LoadRig(CommonOptions* o, app::Config* cfg);

}  // namespace board
}  // namespace ja
