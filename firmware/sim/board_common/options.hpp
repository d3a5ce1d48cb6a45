// The options every virtual board takes (firmware/platform/posix/README.md, the native board's
// table; firmware/sim/avr_board/README.md adds the AVR board's own): the rig, the motion, the
// EEPROM file, the line (baud, serial faults, disconnect and reconnect) and the sensor faults.
// Each board's parser hands every argument to ParseCommonArg first and handles the rest (a board
// in another language: ja_sim_board_open, ja_sim_board.h).
#pragma once

#include <stdint.h>

#include <string>
#include <vector>

#include "sim/board_common/sensor_faults.hpp"

namespace ja {
namespace board {

/// The board's name ("ja_native_board"; copied), the prefix of its messages on stderr.
void SetProgramName(const char* name);
const char* ProgramName();

struct CommonOptions {
  std::string rig, motion, eeprom, link;  // link: a symlink kept to the current pty
  bool fast = false, loop_motion = false;
  bool cold_start = false;  // the BNO055s boot (650 ms of NACKs) when the board starts
  uint32_t baud = 0;        // 0: not given (the board's default)
  uint64_t corrupt_every = 0, drop_every = 0;
  double disconnect_after_s = -1, reconnect_after_s = -1;  // -1: never
  std::vector<SensorFault> faults;
};

enum class ArgResult { kTaken, kNotCommon, kBad };

/// Takes argv[*i] (and its value: *i moves on) when it is a common option. kBad: a missing or
/// malformed value (a malformed --fault is explained on stderr).
ArgResult ParseCommonArg(int argc, char** argv, int* i, CommonOptions* o);
/// `text` as a decimal count (no sign); false when it is not one.
bool ParseCount(const std::string& text, uint64_t* n);
/// `text` as seconds >= 0; false when it is not.
bool ParseSeconds(const std::string& text, double* s);
/// A new directory $TMPDIR/`prefix`-XXXXXX (/tmp without TMPDIR), for the EEPROM file when no
/// --eeprom is given; "" when it cannot be made.
std::string MakeTempDir(const char* prefix);
/// Whether the EEPROM file open on `fd` is new (0 bytes) or an image of `size` bytes; otherwise
/// false with *error saying so (the board then leaves the file as it is: padding it to an image
/// would change someone's file) or why it could not tell.
bool EepromFileFits(int fd, const std::string& path, uint32_t size, std::string* error);
/// The usage on stderr: the common options, then the board's own (`board_options`: lines, each
/// starting with two spaces and ending in \n), the --fault option and its help.
void PrintUsage(const char* board_options);

}  // namespace board
}  // namespace ja
