// Minimal TOML for the rig contract (rig_toml.hpp).
#include "platform/posix/rig_toml.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <vector>

#include "protocol/messages.hpp"
#include "sim/devices/sampling.hpp"

namespace ja {
namespace posix {
namespace {

struct Value {
  enum Kind { kNum, kStr, kBool, kArr } kind = kNum;
  double num = 0;
  std::string str;
  bool b = false;
  std::vector<Value> arr;
};

using Table = std::map<std::string, Value>;

struct Doc {
  std::map<std::string, Table> tables;               // "" = root
  std::map<std::string, std::vector<Table>> arrays;  // [[name]]
};

std::string Trim(const std::string& s) {
  size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

class ValueParser {
 public:
  explicit ValueParser(const std::string& s) : s_(s) {}
  bool Parse(Value* v, std::string* error) {
    if (!ParseValue(v)) {
      *error = "cannot read the value `" + s_ + "`";
      return false;
    }
    Skip();
    if (i_ != s_.size()) {
      *error = "unexpected text after the value `" + s_ + "`";
      return false;
    }
    return true;
  }

 private:
  void Skip() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r'))
      ++i_;
  }
  bool ParseValue(Value* v) {
    Skip();
    if (i_ >= s_.size()) return false;
    const char c = s_[i_];
    if (c == '[') {
      ++i_;
      v->kind = Value::kArr;
      for (;;) {
        Skip();
        if (i_ < s_.size() && s_[i_] == ']') {
          ++i_;
          return true;
        }
        Value e;
        if (!ParseValue(&e)) return false;
        v->arr.push_back(e);
        Skip();
        if (i_ < s_.size() && s_[i_] == ',') {
          ++i_;
          continue;
        }
        if (i_ < s_.size() && s_[i_] == ']') {
          ++i_;
          return true;
        }
        return false;
      }
    }
    if (c == '"' || c == '\'') {
      size_t end = s_.find(c, i_ + 1);
      if (end == std::string::npos) return false;
      v->kind = Value::kStr;
      v->str = s_.substr(i_ + 1, end - i_ - 1);
      i_ = end + 1;
      return true;
    }
    if (s_.compare(i_, 4, "true") == 0) {
      v->kind = Value::kBool;
      v->b = true;
      i_ += 4;
      return true;
    }
    if (s_.compare(i_, 5, "false") == 0) {
      v->kind = Value::kBool;
      i_ += 5;
      return true;
    }
    // Number: decimal, float, hex (0x..), underscores allowed.
    size_t j = i_;
    std::string digits;
    while (j < s_.size() && s_[j] != ',' && s_[j] != ']' && s_[j] != ' ' && s_[j] != '\t' &&
           s_[j] != '\n' && s_[j] != '\r') {
      if (s_[j] != '_') digits += s_[j];
      ++j;
    }
    if (digits.empty()) return false;
    char* end = nullptr;
    const bool hex =
        digits.size() > 2 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X');
    v->kind = Value::kNum;
    v->num = hex ? static_cast<double>(std::strtoll(digits.c_str() + 2, &end, 16))
                 : std::strtod(digits.c_str(), &end);
    if (end == nullptr || *end != '\0') return false;
    i_ = j;
    return true;
  }

  const std::string& s_;
  size_t i_ = 0;
};

// Removes a '#' comment outside strings; returns the bracket depth change outside strings.
int StripComment(std::string* line) {
  int depth = 0;
  char quote = 0;
  for (size_t i = 0; i < line->size(); ++i) {
    const char c = (*line)[i];
    if (quote) {
      if (c == quote) quote = 0;
    } else if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '#') {
      line->resize(i);
      break;
    } else if (c == '[') {
      ++depth;
    } else if (c == ']') {
      --depth;
    }
  }
  return depth;
}

bool ParseDoc(const std::string& text, Doc* doc, std::string* error) {
  std::vector<std::string> lines;
  size_t pos = 0;
  std::string pending;
  int depth = 0;
  int lineno = 0;
  Table* current = &doc->tables[""];
  while (pos <= text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string::npos) nl = text.size();
    std::string line = text.substr(pos, nl - pos);
    pos = nl + 1;
    ++lineno;
    depth += StripComment(&line);
    pending += line + "\n";
    if (depth > 0) continue;
    const std::string logical = Trim(pending);
    pending.clear();
    depth = 0;
    if (logical.empty()) continue;
    if (logical.compare(0, 2, "[[") == 0) {
      if (logical.size() < 4 || logical.compare(logical.size() - 2, 2, "]]") != 0) {
        *error = "line " + std::to_string(lineno) + ": bad table header";
        return false;
      }
      auto& arr = doc->arrays[Trim(logical.substr(2, logical.size() - 4))];
      arr.emplace_back();
      current = &arr.back();
    } else if (logical[0] == '[') {
      if (logical.back() != ']') {
        *error = "line " + std::to_string(lineno) + ": bad table header";
        return false;
      }
      current = &doc->tables[Trim(logical.substr(1, logical.size() - 2))];
    } else {
      const size_t eq = logical.find('=');
      if (eq == std::string::npos) {
        *error = "line " + std::to_string(lineno) + ": expected key = value";
        return false;
      }
      std::string key = Trim(logical.substr(0, eq));
      if (key.size() >= 2 && (key[0] == '"' || key[0] == '\'')) key = key.substr(1, key.size() - 2);
      Value v;
      std::string why;
      if (!ValueParser(Trim(logical.substr(eq + 1))).Parse(&v, &why)) {
        *error = "line " + std::to_string(lineno) + ": " + why;
        return false;
      }
      (*current)[key] = v;
    }
  }
  if (depth > 0) {
    *error = "unterminated array at the end of the file";
    return false;
  }
  return true;
}

bool Number(const Table& t, const char* key, double* out, bool required, const std::string& where,
            std::string* error) {
  auto it = t.find(key);
  if (it == t.end()) {
    if (required) *error = where + ": missing `" + key + "`";
    return !required;
  }
  if (it->second.kind != Value::kNum) {
    *error = where + ": `" + key + "` must be a number";
    return false;
  }
  *out = it->second.num;
  return true;
}

bool Vector(const Value& v, size_t n, double* out) {
  if (v.kind != Value::kArr || v.arr.size() != n) return false;
  for (size_t i = 0; i < n; ++i) {
    if (v.arr[i].kind != Value::kNum) return false;
    out[i] = v.arr[i].num;
  }
  return true;
}

int32_t Micro(double v) { return static_cast<int32_t>(std::llround(v * 1e6)); }

bool InRange(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

std::string Shown(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%g", v);
  return s;
}

}  // namespace

bool RigToConfig(const std::string& text, app::Config* cfg, std::string* sim_spec,
                 std::string* error) {
  Doc doc;
  if (!ParseDoc(text, &doc, error)) return false;
  app::SetDefaults(*cfg);
  const Table& root = doc.tables[""];
  double rate = cfg->rate_hz;
  if (!Number(root, "sample_rate_hz", &rate, false, "rig", error)) return false;
  if (!InRange(rate, app::kMinRateHz, app::kMaxRateHz)) {
    *error = "rig: sample_rate_hz must be 10-1000 Hz on the firmware";
    return false;
  }
  cfg->rate_hz = static_cast<uint16_t>(std::lround(rate));
  sim_spec->clear();
  uint8_t count = 0;
  static const char* const kLinks[2] = {"a", "b"};
  for (int l = 0; l < 2; ++l) {
    const std::string name = std::string("links.") + kLinks[l];
    const Table& link = doc.tables[name];
    double joint[2] = {0, 0};
    auto jt = link.find("joint");
    if (jt != link.end() && !Vector(jt->second, 2, joint)) {
      *error = name + ": `joint` must be [x, y] in metres";
      return false;
    }
    for (int k = 0; k < 2; ++k) {
      if (!InRange(joint[k], -10, 10)) {
        *error = name + ": joint beyond 10 m";
        return false;
      }
      cfg->joint_um[l][k] = Micro(joint[k]);
    }
    const std::vector<Table>& sensors = doc.arrays[name + ".sensors"];
    for (size_t i = 0; i < sensors.size(); ++i) {
      const Table& t = sensors[i];
      const std::string where = name + ".sensors[" + std::to_string(i) + "]";
      if (count >= app::kMaxSensors) {
        *error = where + ": the firmware has " + std::to_string(app::kMaxSensors) + " slots";
        return false;
      }
      auto mt = t.find("model");
      if (mt == t.end() || mt->second.kind != Value::kStr) {
        *error = where + ": missing `model`";
        return false;
      }
      const std::string model = mt->second.str;
      proto::SensorModel m;
      double range = 0;
      if (model == "adxl345") {
        m = proto::SensorModel::kAdxl345;
        range = 2;
      } else if (model == "adxl357") {
        m = proto::SensorModel::kAdxl357;
        range = 10;
      } else if (model == "bno055") {
        m = proto::SensorModel::kBno055;
        range = 2;
      } else {
        *error = where + ": unknown model `" + model + "`";
        return false;
      }
      double pos[2] = {0, 0};
      auto pt = t.find("position");
      if (pt == t.end() || !Vector(pt->second, 2, pos) || !InRange(pos[0], -10, 10) ||
          !InRange(pos[1], -10, 10)) {
        *error = where + ": `position` must be [x, y] in metres (within 10 m)";
        return false;
      }
      double rot = 0, chan = 0, addr = 0x53;
      if (!Number(t, "rotation_deg", &rot, false, where, error) ||
          !Number(t, "mux_channel", &chan, false, where, error) ||
          !Number(t, "address", &addr, false, where, error) ||
          !Number(t, "range_g", &range, false, where, error))
        return false;
      if (!InRange(rot, -3600, 3600) || !InRange(chan, 0, 7) || chan != std::floor(chan) ||
          !InRange(addr, 0x08, 0x77) || addr != std::floor(addr) || !InRange(range, 1, 64)) {
        *error = where + ": rotation_deg, mux_channel (0-7), address or range_g out of range";
        return false;
      }
      app::SensorConfig& s = cfg->sensors[count];
      s.link = static_cast<uint8_t>(l);
      s.model = static_cast<uint8_t>(m);
      s.mux_channel = static_cast<uint8_t>(chan);
      s.address = static_cast<uint8_t>(addr);
      s.range_g = static_cast<uint8_t>(range);
      s.x_um = Micro(pos[0]);
      s.y_um = Micro(pos[1]);
      s.rotation_urad = Micro(rot * M_PI / 180.0);
      if (!app::IsValidSensor(s)) {
        *error = where + ": the firmware cannot run this sensor (range " +
                 std::to_string(s.range_g) + " g for " + model + "?)";
        return false;
      }
      app::Calibration& k = cfg->calibration[count];
      auto st = t.find("S");
      if (st != t.end()) {
        bool ok = st->second.kind == Value::kArr && st->second.arr.size() == 3;
        for (int r = 0; ok && r < 3; ++r) {
          double row[3];
          ok = Vector(st->second.arr[r], 3, row);
          for (int c = 0; ok && c < 3; ++c) {
            ok = InRange(row[c], -100, 100);
            if (ok) k.s_q24[r * 3 + c] = static_cast<int32_t>(std::llround(row[c] * 16777216.0));
          }
        }
        if (!ok) {
          *error = where + ": S must be a 3x3 list of numbers (|S| < 100)";
          return false;
        }
      }
      auto ot = t.find("offset");
      if (ot != t.end()) {
        double o[3];
        if (!Vector(ot->second, 3, o) || !InRange(o[0], -1000, 1000) ||
            !InRange(o[1], -1000, 1000) || !InRange(o[2], -1000, 1000)) {
          *error = where + ": offset must be [ox, oy, oz] in m/s^2";
          return false;
        }
        for (int c = 0; c < 3; ++c) k.o_umps2[c] = Micro(o[c]);
      }
      // Simulation only, for the virtual part (not the firmware's configuration): its conversion
      // clock's oscillator error and grid phase (sim/devices/sampling.hpp), as the spec's clock=.
      double ppm = 0, phase = 0;
      if (!Number(t, "sim_clock_ppm", &ppm, false, where, error) ||
          !Number(t, "sim_clock_phase", &phase, false, where, error))
        return false;
      if (!sim::ValidClockPpm(ppm)) {
        *error = where + ": `sim_clock_ppm` = " + Shown(ppm) +
                 " is out of range: |ppm| < 100000 (the part's oscillator error)";
        return false;
      }
      if (!sim::ValidClockPhase(phase)) {
        *error = where + ": `sim_clock_phase` = " + Shown(phase) +
                 " is out of range: 0 <= phase < 1 (a fraction of the conversion period)";
        return false;
      }
      char line[96];
      std::snprintf(line, sizeof line, "%s.%u %s 0x%02x %u", kLinks[l], static_cast<unsigned>(i),
                    model.c_str(), static_cast<unsigned>(s.address),
                    static_cast<unsigned>(s.mux_channel));
      *sim_spec += line;
      if (ppm != 0 || phase != 0) {
        std::snprintf(line, sizeof line, " clock=%.17g:%.17g", ppm, phase);  // exact round trip
        *sim_spec += line;
      }
      *sim_spec += "\n";
      ++count;
    }
  }
  if (count == 0) {
    *error = "rig: no sensors";
    return false;
  }
  cfg->sensor_count = count;
  for (uint8_t i = count; i < app::kMaxSensors; ++i) {
    cfg->sensors[i].model = static_cast<uint8_t>(proto::SensorModel::kNone);
  }
  if (!app::IsValid(*cfg)) {
    *error = "rig: the firmware rejects this configuration";
    return false;
  }
  return true;
}

}  // namespace posix
}  // namespace ja
