#include "sim/board_common/options.hpp"

#include <errno.h>
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace ja {
namespace board {
namespace {
std::string& Program() {
  static std::string name = "ja_board";
  return name;
}
}  // namespace

void SetProgramName(const char* name) { Program() = name ? name : "ja_board"; }
const char* ProgramName() { return Program().c_str(); }

bool ParseCount(const std::string& text, uint64_t* n) {
  char* end = nullptr;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (*end != '\0' || text.empty() || text[0] == '-') return false;
  *n = v;
  return true;
}

bool ParseSeconds(const std::string& text, double* s) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (*end != '\0' || text.empty() || !(v >= 0)) return false;
  *s = v;
  return true;
}

ArgResult ParseCommonArg(int argc, char** argv, int* i, CommonOptions* o) {
  const std::string a = argv[*i];
  std::string v;
  auto next = [&](std::string* out) {
    if (*i + 1 >= argc) return false;
    *out = argv[++*i];
    return true;
  };
  auto taken = [](bool ok) { return ok ? ArgResult::kTaken : ArgResult::kBad; };
  if (a == "--fast") {
    o->fast = true;
  } else if (a == "--loop-motion") {
    o->loop_motion = true;
  } else if (a == "--cold-start") {
    o->cold_start = true;
  } else if (a == "--fault") {
    if (!next(&v)) return ArgResult::kBad;
    SensorFault f;
    std::string why;
    if (!ParseSensorFault(v, &f, &why)) {
      std::fprintf(stderr, "%s: --fault %s: %s\n", ProgramName(), v.c_str(), why.c_str());
      return ArgResult::kBad;
    }
    o->faults.push_back(f);
  } else if (a == "--rig") {
    return taken(next(&o->rig));
  } else if (a == "--motion") {
    return taken(next(&o->motion));
  } else if (a == "--eeprom") {
    return taken(next(&o->eeprom));
  } else if (a == "--link") {
    return taken(next(&o->link));
  } else if (a == "--baud") {
    uint64_t n = 0;
    if (!next(&v) || !ParseCount(v, &n) || n < 300 || n > 10000000) return ArgResult::kBad;
    o->baud = static_cast<uint32_t>(n);
  } else if (a == "--corrupt-every") {
    return taken(next(&v) && ParseCount(v, &o->corrupt_every));
  } else if (a == "--drop-every") {
    return taken(next(&v) && ParseCount(v, &o->drop_every));
  } else if (a == "--disconnect-after") {
    return taken(next(&v) && ParseSeconds(v, &o->disconnect_after_s));
  } else if (a == "--reconnect-after") {
    return taken(next(&v) && ParseSeconds(v, &o->reconnect_after_s));
  } else {
    return ArgResult::kNotCommon;
  }
  return ArgResult::kTaken;
}

std::string MakeTempDir(const char* prefix) {
  const char* base = std::getenv("TMPDIR");
  std::string tmpl = std::string(base && *base ? base : "/tmp") + "/" + prefix + "-XXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  if (mkdtemp(buf.data()) == nullptr) return "";
  return buf.data();
}

bool EepromFileFits(int fd, const std::string& path, uint32_t size, std::string* error) {
  struct stat st;
  if (fstat(fd, &st) != 0) {
    *error = "cannot read the EEPROM file " + path + ": " + std::strerror(errno);
    return false;
  }
  if (st.st_size != 0 && st.st_size != static_cast<off_t>(size)) {
    *error = path + " is not an EEPROM image of this board (" +
             std::to_string(static_cast<long long>(st.st_size)) + " bytes, an image has " +
             std::to_string(size) + " or the file is new): left as it is";
    return false;
  }
  return true;
}

void PrintUsage(const char* board_options) {
  std::fprintf(stderr,
               "usage: %s --rig RIG.toml --motion DATA.csv [--baud B] [--fast]\n"
               "  [--eeprom FILE] [--link PATH] [--loop-motion] [--corrupt-every N]\n"
               "  [--drop-every N] [--disconnect-after S] [--reconnect-after S] [--cold-start]\n"
               "%s"
               "  [--fault SENSOR:KIND[=PARAM]@START[-END]]...  (repeatable)\n"
               "    SENSOR a.0, a.1, b.0, ... (rig order) or mux; KIND nack, wrong_id,\n"
               "    saturate, frozen (PARAM: firmware/sim/devices/i2c_target.hpp FaultKind);\n"
               "    START, END in simulated seconds (no END: until the board stops)\n"
               "    e.g. --fault a.0:nack@2.0-4.0 --fault b.1:frozen@1\n"
               "  --cold-start: the parts power up with the board (a BNO055 boots 650 ms)\n",
               ProgramName(), board_options ? board_options : "");
}

}  // namespace board
}  // namespace ja
