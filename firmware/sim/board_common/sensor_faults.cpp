#include "sim/board_common/sensor_faults.hpp"

#include <cstdio>
#include <cstdlib>

#include "sim/board_common/options.hpp"

namespace ja {
namespace board {

bool ParseSensorFault(const std::string& text, SensorFault* f, std::string* why) {
  const size_t colon = text.find(':'), at = text.find('@');
  if (colon == std::string::npos || at == std::string::npos || colon == 0 || at < colon) {
    *why = "expected SENSOR:KIND[=PARAM]@START[-END], e.g. a.0:nack@2-4";
    return false;
  }
  f->sensor = text.substr(0, colon);
  std::string kind = text.substr(colon + 1, at - colon - 1);
  const size_t eq = kind.find('=');
  if (eq != std::string::npos) {
    const std::string v = kind.substr(eq + 1);
    char* end = nullptr;
    const unsigned long long n = std::strtoull(v.c_str(), &end, 0);
    if (v.empty() || *end != '\0' || v[0] == '-' || n > 0xFFFFFFFFull) {
      *why = "PARAM must be an integer 0..2^32-1";
      return false;
    }
    f->param = static_cast<uint32_t>(n);
    kind = kind.substr(0, eq);
  }
  if (kind == "nack") {
    f->kind = JA_SIM_FAULT_NACK;
  } else if (kind == "wrong_id" || kind == "wrong-id") {
    f->kind = JA_SIM_FAULT_WRONG_ID;
  } else if (kind == "saturate" || kind == "saturated") {
    f->kind = JA_SIM_FAULT_SATURATE;
  } else if (kind == "frozen") {
    f->kind = JA_SIM_FAULT_FROZEN;
  } else {
    *why = "unknown fault kind '" + kind + "' (nack, wrong_id, saturate, frozen)";
    return false;
  }
  const std::string times = text.substr(at + 1);
  const char* p = times.c_str();
  char* end = nullptr;
  const double start = std::strtod(p, &end);
  double stop = -1;
  bool ok = end != p && start >= 0 && start <= 1e6;
  if (ok && *end == '-') {
    const char* q = end + 1;
    stop = std::strtod(q, &end);
    ok = end != q && stop > start && stop <= 1e6;
  }
  if (!ok || *end != '\0') {
    *why = "START[-END] must be seconds with END > START >= 0";
    return false;
  }
  f->start_ns = static_cast<uint64_t>(start * 1e9 + 0.5);
  if (stop >= 0) f->end_ns = static_cast<uint64_t>(stop * 1e9 + 0.5);
  return true;
}

bool ResolveSensorFaults(ja_sim* sim, std::vector<SensorFault>* faults, std::string* why) {
  for (SensorFault& f : *faults) {
    f.dev = -1;
    if (f.sensor == "mux") {
      for (int d = 0; d < ja_sim_device_count(sim) && f.dev < 0; ++d) {
        int model = 0;
        if (ja_sim_device_info(sim, d, &model, nullptr, nullptr, nullptr) == JA_SIM_OK &&
            model == JA_SIM_TCA9548A)
          f.dev = d;
      }
    } else {
      f.dev = ja_sim_find_device(sim, f.sensor.c_str());
    }
    if (f.dev < 0) {
      *why =
          "the rig has no sensor '" + f.sensor + "' (a.0, a.1, ..., b.0, ... in rig order, or mux)";
      return false;
    }
  }
  return true;
}

void ApplySensorFaults(ja_sim* sim, std::vector<SensorFault>* faults, uint64_t now_ns) {
  for (SensorFault& f : *faults) {
    if (f.done) continue;
    if (!f.on && now_ns >= f.start_ns) {
      if (ja_sim_inject_fault(sim, f.dev, f.kind, f.param) != JA_SIM_OK) {
        std::fprintf(stderr, "%s: --fault %s: %s\n", ProgramName(), f.sensor.c_str(),
                     ja_sim_last_error(sim));
        f.done = true;
        continue;
      }
      f.on = true;
      std::fprintf(stderr, "%s: %.3f s: fault %d on %s\n", ProgramName(), now_ns * 1e-9, f.kind,
                   f.sensor.c_str());
    }
    if (f.on && now_ns >= f.end_ns) {
      ja_sim_clear_fault(sim, f.dev, f.kind);
      f.on = false;
      f.done = true;
      std::fprintf(stderr, "%s: %.3f s: fault %d off %s\n", ProgramName(), now_ns * 1e-9, f.kind,
                   f.sensor.c_str());
    }
  }
}

}  // namespace board
}  // namespace ja
