// The C ABI of ja_sim_devices.h: a context owning one Bus, its devices and their motion.
#include "sim/devices/ja_sim_devices.h"

#include <stdlib.h>
#include <string.h>

#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "sim/devices/adxl345.hpp"
#include "sim/devices/adxl357.hpp"
#include "sim/devices/bno055.hpp"
#include "sim/devices/bus.hpp"
#include "sim/devices/motion_csv.hpp"
#include "sim/devices/tca9548a.hpp"

using ja::sim::Adxl345;
using ja::sim::Adxl357;
using ja::sim::Bno055;
using ja::sim::ConstantMotion;
using ja::sim::FaultKind;
using ja::sim::I2cTarget;
using ja::sim::MotionSource;
using ja::sim::MotionTrack;
using ja::sim::Oscillator;
using ja::sim::Tca9548a;

struct ja_sim {
  struct Device {
    std::unique_ptr<I2cTarget> dev;
    int model;
    int mux;
    int channel;
    std::string motion_id;
    std::unique_ptr<ConstantMotion> constant;  // set: overrides the track
  };
  ja::sim::Bus bus;
  std::vector<Device> devices;
  ja::sim::NamedTracks tracks;
  bool loop = false;
  std::string error;

  int Fail(const std::string& why) {
    error = why;
    return JA_SIM_EINVAL;
  }
  bool Valid(int dev) const { return dev >= 0 && dev < static_cast<int>(devices.size()); }

  const MotionSource* MotionFor(const Device& d) const {
    if (d.constant) return d.constant.get();
    for (const auto& t : tracks) {
      if (!d.motion_id.empty() && t.first == d.motion_id) return t.second.get();
    }
    return nullptr;
  }
  /// Rebinds every sensor to its motion; returns how many have one.
  int Bind() {
    int bound = 0;
    for (Device& d : devices) {
      const MotionSource* m = MotionFor(d);
      if (m) ++bound;
      switch (d.model) {
        case JA_SIM_ADXL345:
          static_cast<Adxl345*>(d.dev.get())->set_motion(m);
          break;
        case JA_SIM_ADXL357:
          static_cast<Adxl357*>(d.dev.get())->set_motion(m);
          break;
        case JA_SIM_BNO055:
          static_cast<Bno055*>(d.dev.get())->set_motion(m);
          break;
        default:
          if (m) --bound;
          break;
      }
    }
    for (auto& t : tracks) t.second->set_loop(loop);
    return bound;
  }

  /// Sets a sensor's oscillator; JA_SIM_OK or a failure naming what is wrong.
  int SetClock(int dev, const Oscillator& o) {
    if (!Valid(dev)) return Fail("device " + std::to_string(dev) + " does not exist");
    const std::string why = ClockProblem(o);
    if (!why.empty()) return Fail("device " + std::to_string(dev) + ": " + why);
    Device& d = devices[dev];
    switch (d.model) {
      case JA_SIM_ADXL345:
        static_cast<Adxl345*>(d.dev.get())->set_oscillator(o);
        break;
      case JA_SIM_ADXL357:
        static_cast<Adxl357*>(d.dev.get())->set_oscillator(o);
        break;
      case JA_SIM_BNO055:
        static_cast<Bno055*>(d.dev.get())->set_oscillator(o);
        break;
      default:
        return Fail("device " + std::to_string(dev) + " is a multiplexer: it has no clock");
    }
    return JA_SIM_OK;
  }
  /// Why `o` is not a valid oscillator ("" if it is).
  static std::string ClockProblem(const Oscillator& o) {
    std::ostringstream why;
    if (!std::isfinite(o.ppm) || !std::isfinite(o.phase)) {
      why << "clock ppm " << o.ppm << " and phase " << o.phase << " must be finite";
    } else if (!ja::sim::ValidClockPpm(o.ppm)) {
      why << "clock ppm " << o.ppm << " is out of range (|ppm| < 100000)";
    } else if (!ja::sim::ValidClockPhase(o.phase)) {
      why << "clock phase " << o.phase << " is out of range (0 <= phase < 1)";
    }
    return why.str();
  }

  int Add(std::unique_ptr<I2cTarget> dev, int model, int mux, int channel, const char* id) {
    const Tca9548a* parent = nullptr;
    if (mux >= 0) {
      if (!Valid(mux) || devices[mux].model != JA_SIM_TCA9548A) {
        return Fail("device " + std::to_string(mux) + " is not a multiplexer");
      }
      parent = static_cast<const Tca9548a*>(devices[mux].dev.get());
    }
    if (mux >= 0 && (channel < 0 || channel >= Tca9548a::kChannels)) {
      return Fail("mux channel " + std::to_string(channel) + " is not 0..7");
    }
    if (!bus.Attach(dev.get(), parent, static_cast<uint8_t>(mux >= 0 ? channel : 0))) {
      return Fail("the bus is full (32 devices)");
    }
    Device d;
    d.dev = std::move(dev);
    d.model = model;
    d.mux = mux;
    d.channel = mux >= 0 ? channel : -1;
    d.motion_id = id ? id : "";
    devices.push_back(std::move(d));
    Bind();
    return static_cast<int>(devices.size()) - 1;
  }
};

namespace {

int ModelFromName(const std::string& name) {
  if (name == "adxl345") return JA_SIM_ADXL345;
  if (name == "adxl357") return JA_SIM_ADXL357;
  if (name == "bno055") return JA_SIM_BNO055;
  if (name == "tca9548a") return JA_SIM_TCA9548A;
  return 0;
}

bool ParseInt(const std::string& s, long* out) {
  if (s.empty()) return false;
  char* end = nullptr;
  *out = strtol(s.c_str(), &end, 0);
  return *end == '\0';
}

bool ParseDouble(const std::string& s, double* out) {
  if (s.empty()) return false;
  char* end = nullptr;
  *out = strtod(s.c_str(), &end);
  return *end == '\0';
}

/// "clock=<ppm>:<phase>" -> o (values unchecked); false if it does not have that shape.
bool ParseClockField(const std::string& f, Oscillator* o) {
  static const std::string kKey = "clock=";
  if (f.compare(0, kKey.size(), kKey) != 0) return false;
  const std::string v = f.substr(kKey.size());
  const size_t colon = v.find(':');
  if (colon == std::string::npos) return false;
  return ParseDouble(v.substr(0, colon), &o->ppm) && ParseDouble(v.substr(colon + 1), &o->phase);
}

}  // namespace

extern "C" {

uint32_t ja_sim_abi_version(void) { return JA_SIM_ABI_VERSION; }

ja_sim* ja_sim_create(void) { return new ja_sim(); }

void ja_sim_destroy(ja_sim* sim) { delete sim; }

const char* ja_sim_last_error(const ja_sim* sim) { return sim ? sim->error.c_str() : "no sim"; }

int ja_sim_add_mux(ja_sim* sim, uint8_t addr7, int mux, int channel) {
  if (!sim) return JA_SIM_EINVAL;
  if (addr7 > 0x7F) return sim->Fail("address above 0x7F");
  return sim->Add(std::unique_ptr<I2cTarget>(new Tca9548a(addr7)), JA_SIM_TCA9548A, mux, channel,
                  nullptr);
}

int ja_sim_add_device(ja_sim* sim, int model, uint8_t addr7, int mux, int channel,
                      const char* motion_id) {
  if (!sim) return JA_SIM_EINVAL;
  if (addr7 > 0x7F) return sim->Fail("address above 0x7F");
  std::unique_ptr<I2cTarget> dev;
  switch (model) {
    case JA_SIM_ADXL345:
      dev.reset(new Adxl345(addr7));
      break;
    case JA_SIM_ADXL357:
      dev.reset(new Adxl357(addr7));
      break;
    case JA_SIM_BNO055:
      dev.reset(new Bno055(addr7));
      break;
    case JA_SIM_TCA9548A:
      return ja_sim_add_mux(sim, addr7, mux, channel);
    default:
      return sim->Fail("unknown model " + std::to_string(model));
  }
  return sim->Add(std::move(dev), model, mux, channel, motion_id);
}

int ja_sim_attach_rig(ja_sim* sim, const char* spec) {
  if (!sim || !spec) return JA_SIM_EINVAL;
  struct Line {
    std::string id;
    int model;
    long addr;
    long channel;
    bool has_clock;
    Oscillator clock;
  };
  std::vector<Line> sensors;
  long mux_addr = Tca9548a::kBaseAddress;
  std::istringstream in(spec);
  std::string text;
  int lineno = 0;
  while (std::getline(in, text)) {
    ++lineno;
    const size_t hash = text.find('#');
    if (hash != std::string::npos) text.erase(hash);
    std::istringstream fields(text);
    std::vector<std::string> f;
    std::string w;
    while (fields >> w) f.push_back(w);
    if (f.empty()) continue;
    const std::string where = "rig line " + std::to_string(lineno) + ": ";
    if (f[0] == "mux") {
      if (f.size() != 2 || !ParseInt(f[1], &mux_addr) || mux_addr < 0 || mux_addr > 0x7F) {
        return sim->Fail(where + "expected 'mux <address>'");
      }
      continue;
    }
    Line l;
    if (f.size() != 4 && f.size() != 5) {
      return sim->Fail(where + "expected '<id> <model> <address> <channel> [clock=<ppm>:<phase>]'");
    }
    l.id = f[0];
    l.model = ModelFromName(f[1]);
    if (l.model == 0 || l.model == JA_SIM_TCA9548A) {
      return sim->Fail(where + "unknown sensor model '" + f[1] + "'");
    }
    if (!ParseInt(f[2], &l.addr) || l.addr < 0 || l.addr > 0x7F) {
      return sim->Fail(where + "bad address '" + f[2] + "'");
    }
    if (!ParseInt(f[3], &l.channel) || l.channel < -1 || l.channel > 7) {
      return sim->Fail(where + "bad mux channel '" + f[3] + "' (0..7, or -1 for none)");
    }
    l.has_clock = f.size() == 5;
    if (l.has_clock) {
      if (!ParseClockField(f[4], &l.clock)) {
        return sim->Fail(where + "bad clock field '" + f[4] + "' (expected clock=<ppm>:<phase>)");
      }
      const std::string why = ja_sim::ClockProblem(l.clock);
      if (!why.empty()) return sim->Fail(where + "field '" + f[4] + "': " + why);
    }
    sensors.push_back(l);
  }
  int mux = -1;
  for (const Line& l : sensors) {
    if (l.channel >= 0 && mux < 0) {
      mux = ja_sim_add_mux(sim, static_cast<uint8_t>(mux_addr), -1, 0);
      if (mux < 0) return mux;
    }
    const int d =
        ja_sim_add_device(sim, l.model, static_cast<uint8_t>(l.addr), l.channel >= 0 ? mux : -1,
                          static_cast<int>(l.channel), l.id.c_str());
    if (d < 0) return d;
    if (l.has_clock && sim->SetClock(d, l.clock) != JA_SIM_OK) return JA_SIM_EINVAL;
  }
  return static_cast<int>(sensors.size());
}

int ja_sim_device_count(const ja_sim* sim) {
  return sim ? static_cast<int>(sim->devices.size()) : JA_SIM_EINVAL;
}

int ja_sim_device_info(const ja_sim* sim, int dev, int* model, int* addr7, int* mux, int* channel) {
  if (!sim || !sim->Valid(dev)) return JA_SIM_EINVAL;
  const ja_sim::Device& d = sim->devices[dev];
  if (model) *model = d.model;
  if (addr7) *addr7 = d.dev->address();
  if (mux) *mux = d.mux;
  if (channel) *channel = d.channel;
  return JA_SIM_OK;
}

int ja_sim_find_device(const ja_sim* sim, const char* motion_id) {
  if (!sim || !motion_id) return JA_SIM_EINVAL;
  for (size_t i = 0; i < sim->devices.size(); ++i) {
    if (sim->devices[i].motion_id == motion_id) return static_cast<int>(i);
  }
  return JA_SIM_EINVAL;
}

int ja_sim_set_clock(ja_sim* sim, int device, double ppm, double phase) {
  if (!sim) return JA_SIM_EINVAL;
  Oscillator o;
  o.ppm = ppm;
  o.phase = phase;
  return sim->SetClock(device, o);
}

int ja_sim_load_motion_csv(ja_sim* sim, const char* path) {
  if (!sim || !path) return JA_SIM_EINVAL;
  ja::sim::NamedTracks tracks;
  std::string error;
  if (!ja::sim::LoadAccelCsv(path, &tracks, &error)) return sim->Fail(error);
  for (auto& d : sim->devices) d.constant.reset();
  sim->tracks = std::move(tracks);
  return sim->Bind();
}

int ja_sim_set_motion(ja_sim* sim, const char* motion_id, size_t rows, const double* t_s,
                      const double* accel, const double* gyro) {
  if (!sim || !motion_id || !*motion_id || !t_s || !accel || rows == 0) return JA_SIM_EINVAL;
  std::unique_ptr<MotionTrack> track(new MotionTrack());
  for (size_t i = 0; i < rows; ++i) {
    if (!track->Append(t_s[i], accel + 3 * i, gyro ? gyro + 3 * i : nullptr)) {
      return sim->Fail("row " + std::to_string(i) + ": time does not increase");
    }
  }
  bool replaced = false;
  for (auto& t : sim->tracks) {
    if (t.first == motion_id) {
      t.second = std::move(track);
      replaced = true;
      break;
    }
  }
  if (!replaced) sim->tracks.emplace_back(motion_id, std::move(track));
  for (auto& d : sim->devices) {
    if (d.motion_id == motion_id) d.constant.reset();
  }
  return sim->Bind();
}

int ja_sim_set_constant_motion(ja_sim* sim, int dev, const double accel[3], const double* gyro) {
  if (!sim || !sim->Valid(dev) || !accel) return JA_SIM_EINVAL;
  ja_sim::Device& d = sim->devices[dev];
  if (d.model == JA_SIM_TCA9548A) return sim->Fail("a multiplexer has no motion");
  d.constant.reset(new ConstantMotion(accel[0], accel[1], accel[2]));
  if (gyro) d.constant->SetGyro(gyro[0], gyro[1], gyro[2]);
  sim->Bind();
  return JA_SIM_OK;
}

int ja_sim_set_motion_loop(ja_sim* sim, int loop) {
  if (!sim) return JA_SIM_EINVAL;
  sim->loop = loop != 0;
  sim->Bind();
  return JA_SIM_OK;
}

int ja_sim_set_time_us(ja_sim* sim, uint64_t t_us) {
  if (!sim) return JA_SIM_EINVAL;
  return sim->bus.SetTimeUs(t_us) ? JA_SIM_OK : 1;
}

int ja_sim_set_time_ns(ja_sim* sim, uint64_t t_ns) {
  if (!sim) return JA_SIM_EINVAL;
  return sim->bus.SetTimeNs(t_ns) ? JA_SIM_OK : 1;
}

uint64_t ja_sim_time_ns(const ja_sim* sim) { return sim ? sim->bus.time_ns() : 0; }

int ja_sim_set_scl_hz(ja_sim* sim, uint32_t hz) {
  if (!sim) return JA_SIM_EINVAL;
  sim->bus.set_scl_hz(hz);
  return JA_SIM_OK;
}

int ja_sim_bus_start(ja_sim* sim) {
  if (!sim) return JA_SIM_EINVAL;
  sim->bus.Start();
  return JA_SIM_OK;
}

int ja_sim_bus_write_byte(ja_sim* sim, uint8_t byte) {
  if (!sim) return JA_SIM_EINVAL;
  return sim->bus.WriteByte(byte) ? 1 : 0;
}

int ja_sim_bus_read_byte(ja_sim* sim, int master_ack) {
  if (!sim) return JA_SIM_EINVAL;
  return sim->bus.ReadByte(master_ack != 0);
}

int ja_sim_bus_stop(ja_sim* sim) {
  if (!sim) return JA_SIM_EINVAL;
  sim->bus.Stop();
  return JA_SIM_OK;
}

int ja_sim_i2c_write(ja_sim* sim, uint8_t addr7, const uint8_t* data, size_t n) {
  if (!sim || (n && !data)) return JA_SIM_EINVAL;
  return static_cast<int>(sim->bus.Write(addr7, data, n));
}

int ja_sim_i2c_read(ja_sim* sim, uint8_t addr7, uint8_t* data, size_t n) {
  if (!sim || (n && !data)) return JA_SIM_EINVAL;
  return static_cast<int>(sim->bus.Read(addr7, data, n));
}

int ja_sim_i2c_write_read(ja_sim* sim, uint8_t addr7, const uint8_t* w, size_t nw, uint8_t* r,
                          size_t nr) {
  if (!sim || (nw && !w) || (nr && !r)) return JA_SIM_EINVAL;
  return static_cast<int>(sim->bus.WriteRead(addr7, w, nw, r, nr));
}

int ja_sim_inject_fault(ja_sim* sim, int dev, int kind, uint32_t param) {
  if (!sim || !sim->Valid(dev)) return JA_SIM_EINVAL;
  I2cTarget& d = *sim->devices[dev].dev;
  if (kind < 1 || kind > 4 || !d.SetFault(static_cast<FaultKind>(kind), true, param)) {
    return sim->Fail(std::string("fault ") + std::to_string(kind) + " is not modelled on " +
                     d.model());
  }
  return JA_SIM_OK;
}

int ja_sim_clear_fault(ja_sim* sim, int dev, int kind) {
  if (!sim || !sim->Valid(dev)) return JA_SIM_EINVAL;
  I2cTarget& d = *sim->devices[dev].dev;
  if (kind == 0) {
    d.ClearFaults();
    return JA_SIM_OK;
  }
  if (kind < 1 || kind > 4) return sim->Fail("unknown fault kind");
  d.SetFault(static_cast<FaultKind>(kind), false);
  return JA_SIM_OK;
}

int ja_sim_power_cycle(ja_sim* sim, int dev) {
  if (!sim || !sim->Valid(dev)) return JA_SIM_EINVAL;
  sim->devices[dev].dev->PowerOnReset();
  return JA_SIM_OK;
}

int ja_sim_set_earth_field(ja_sim* sim, int dev, const double field_ut[3], double heading_deg) {
  if (!sim) return JA_SIM_EINVAL;
  if (!sim->Valid(dev) || sim->devices[dev].model != JA_SIM_BNO055) {
    return sim->Fail("device " + std::to_string(dev) + " is not a bno055");
  }
  if (!field_ut) return sim->Fail("no field");
  Bno055* b = static_cast<Bno055*>(sim->devices[dev].dev.get());
  b->fusion().set_earth_field(field_ut);
  b->fusion().set_initial_heading_deg(heading_deg);
  return JA_SIM_OK;
}

int ja_sim_get_device_counters(const ja_sim* sim, int dev, ja_sim_device_counters* out,
                               size_t size) {
  if (!sim || !sim->Valid(dev) || !out || size != sizeof(ja_sim_device_counters)) {
    return JA_SIM_EINVAL;
  }
  const ja::sim::DeviceCounters& c = sim->devices[dev].dev->counters();
  *out = ja_sim_device_counters{c.transactions, c.address_nacks,  c.bytes_written,
                                c.bytes_read,   c.samples,        c.samples_read,
                                c.overruns,     c.writes_ignored, c.config_violations};
  return JA_SIM_OK;
}

int ja_sim_get_bus_counters(const ja_sim* sim, ja_sim_bus_counters* out, size_t size) {
  if (!sim || !out || size != sizeof(ja_sim_bus_counters)) return JA_SIM_EINVAL;
  const ja::sim::BusCounters& c = sim->bus.counters();
  *out = ja_sim_bus_counters{c.starts,        c.repeated_starts, c.stops,         c.address_acks,
                             c.address_nacks, c.data_nacks,      c.bytes_written, c.bytes_read,
                             c.bus_errors,    c.scl_bits};
  return JA_SIM_OK;
}

}  // extern "C"
