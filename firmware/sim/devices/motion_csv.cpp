#include "sim/devices/motion_csv.hpp"

#include <stdio.h>
#include <stdlib.h>

namespace ja {
namespace sim {

namespace {

std::vector<std::string> SplitFields(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    std::string f =
        line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    while (!f.empty() && (f.back() == '\r' || f.back() == ' ')) f.pop_back();
    while (!f.empty() && f.front() == ' ') f.erase(0, 1);
    out.push_back(f);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

struct Columns {
  std::string id;
  int accel[3] = {-1, -1, -1};
  int gyro[3] = {-1, -1, -1};
};

}  // namespace

bool ParseAccelCsv(const std::string& text, NamedTracks* out, std::string* error) {
  out->clear();
  size_t pos = 0;
  int lineno = 0;
  std::vector<std::string> header;
  std::vector<Columns> sensors;
  std::vector<double> row;
  while (pos < text.size()) {
    const size_t nl = text.find('\n', pos);
    const std::string line =
        text.substr(pos, nl == std::string::npos ? std::string::npos : nl - pos);
    pos = nl == std::string::npos ? text.size() : nl + 1;
    ++lineno;
    if (line.find_first_not_of(" \r\t") == std::string::npos) continue;
    std::vector<std::string> f = SplitFields(line);
    if (header.empty()) {
      header = f;
      if (header[0] != "t") {
        *error = "line 1: the first column must be 't', found '" + header[0] + "'";
        return false;
      }
      for (size_t c = 1; c < header.size(); ++c) {
        const std::string& name = header[c];
        const size_t dot = name.rfind('.');
        if (dot == std::string::npos || name.find('.') == dot) continue;  // theta, omega_a, ...
        const std::string id = name.substr(0, dot), axis = name.substr(dot + 1);
        static const char* const kAxes[6] = {"x", "y", "z", "gx", "gy", "gz"};
        int k = -1;
        for (int a = 0; a < 6; ++a) {
          if (axis == kAxes[a]) k = a;
        }
        if (k < 0) continue;
        size_t s = 0;
        while (s < sensors.size() && sensors[s].id != id) ++s;
        if (s == sensors.size()) {
          sensors.push_back(Columns());
          sensors.back().id = id;
        }
        (k < 3 ? sensors[s].accel[k] : sensors[s].gyro[k - 3]) = static_cast<int>(c);
      }
      for (const Columns& s : sensors) {
        if (s.accel[0] < 0 || s.accel[1] < 0 || s.accel[2] < 0) {
          *error = "line 1: sensor '" + s.id + "' lacks one of its x, y, z columns";
          return false;
        }
        const int g = (s.gyro[0] >= 0) + (s.gyro[1] >= 0) + (s.gyro[2] >= 0);
        if (g != 0 && g != 3) {
          *error = "line 1: sensor '" + s.id + "' has some but not all of gx, gy, gz";
          return false;
        }
      }
      if (sensors.empty()) {
        *error = "line 1: no sensor columns (<link>.<i>.x)";
        return false;
      }
      for (const Columns& s : sensors) {
        out->emplace_back(s.id, std::unique_ptr<MotionTrack>(new MotionTrack()));
      }
      continue;
    }
    if (f.size() != header.size()) {
      *error = "line " + std::to_string(lineno) + ": " + std::to_string(f.size()) +
               " fields, the header has " + std::to_string(header.size());
      return false;
    }
    row.assign(f.size(), 0.0);
    for (size_t c = 0; c < f.size(); ++c) {
      const char* s = f[c].c_str();
      char* end = nullptr;
      row[c] = strtod(s, &end);
      if (f[c].empty() || *end != '\0') {
        *error = "line " + std::to_string(lineno) + ", field '" + header[c] + "': not a number: '" +
                 f[c] + "'";
        return false;
      }
    }
    for (size_t s = 0; s < sensors.size(); ++s) {
      const double a[3] = {row[sensors[s].accel[0]], row[sensors[s].accel[1]],
                           row[sensors[s].accel[2]]};
      double g[3] = {0, 0, 0};
      const bool has_gyro = sensors[s].gyro[0] >= 0;
      if (has_gyro) {
        for (int k = 0; k < 3; ++k) g[k] = row[sensors[s].gyro[k]];
      }
      if (!(*out)[s].second->Append(row[0], a, has_gyro ? g : nullptr)) {
        *error = "line " + std::to_string(lineno) + ", field 't': time does not increase";
        return false;
      }
    }
  }
  if (header.empty() || (*out)[0].second->rows() == 0) {
    *error = "no data rows";
    out->clear();
    return false;
  }
  return true;
}

bool LoadAccelCsv(const char* path, NamedTracks* out, std::string* error) {
  FILE* f = fopen(path, "rb");
  if (!f) {
    *error = std::string("cannot open ") + path;
    return false;
  }
  std::string text;
  char buf[65536];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
  fclose(f);
  if (!ParseAccelCsv(text, out, error)) {
    *error = std::string(path) + ": " + *error;
    return false;
  }
  return true;
}

}  // namespace sim
}  // namespace ja
