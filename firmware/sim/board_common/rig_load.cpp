#include "sim/board_common/rig_load.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "platform/posix/rig_toml.hpp"

namespace ja {
namespace board {

SimPtr LoadRig(CommonOptions* o, app::Config* cfg, std::string* error) {
  std::ifstream rig_in(o->rig);
  if (!rig_in) {
    *error = "cannot read the rig " + o->rig;
    return nullptr;
  }
  std::stringstream rig_text;
  rig_text << rig_in.rdbuf();
  std::string spec, why;
  if (!posix::RigToConfig(rig_text.str(), cfg, &spec, &why)) {
    *error = o->rig + ": " + why;
    return nullptr;
  }
  SimPtr sim(ja_sim_create());
  if (ja_sim_attach_rig(sim.get(), spec.c_str()) < 0 ||
      ja_sim_load_motion_csv(sim.get(), o->motion.c_str()) < 0) {
    *error = ja_sim_last_error(sim.get());
    return nullptr;
  }
  if (o->loop_motion) ja_sim_set_motion_loop(sim.get(), 1);
  if (o->cold_start) {  // powered up with the board: a BNO055 answers after its boot
    for (int i = 0; i < ja_sim_device_count(sim.get()); ++i) {
      int model = 0;
      if (ja_sim_device_info(sim.get(), i, &model, nullptr, nullptr, nullptr) == JA_SIM_OK &&
          model == JA_SIM_BNO055) {
        ja_sim_power_cycle(sim.get(), i);
      }
    }
  }
  if (!ResolveSensorFaults(sim.get(), &o->faults, &why)) {
    *error = "--fault: " + why;
    return nullptr;
  }
  return sim;
}

SimPtr LoadRig(CommonOptions* o, app::Config* cfg) {
  std::string error;
  SimPtr sim = LoadRig(o, cfg, &error);
  if (!sim) std::fprintf(stderr, "%s: %s\n", ProgramName(), error.c_str());
  return sim;
}

}  // namespace board
}  // namespace ja
