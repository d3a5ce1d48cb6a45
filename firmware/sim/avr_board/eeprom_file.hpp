// The simulated ATmega2560's EEPROM (4 KB) kept in a file, so a watchdog reset (simavr keeps the
// EEPROM across avr_reset) and a restart of the board both find what the firmware saved.
// A missing or empty file is created with the rig's configuration written by the application's
// own SaveConfig (app/app_config.hpp), as on the native board; an existing file is used as it is.
// Without --eeprom the file lives in a temporary directory removed at exit. The file is
// board_common's SettingsFile (shared with any board through ja_sim_board.h); this class puts it
// into simavr's EEPROM and times the writes.
#pragma once

#include <stdint.h>

#include <string>

#include "app/app_config.hpp"
#include "sim/board_common/settings_file.hpp"

struct avr_t;

namespace ja {
namespace avrboard {

class EepromFile {
 public:
  static constexpr uint16_t kSize = 4096;
  explicit EepromFile(avr_t* avr) : avr_(avr) {}
  /// Opens (or creates) `path` ("" = a temporary file) and loads it into the simulated EEPROM.
  /// A new file starts with `cfg` saved as the firmware does, or erased (0xFF) with `erased`
  /// (an image other than the project's: a new chip).
  bool Open(const std::string& path, const app::Config& cfg, bool erased, std::string* error);
  /// Writes the bytes the firmware changed since the last call to the file.
  void Persist();
  /// simavr 1.6 finishes an EEPROM write at once (EEPE reads 0 right after the write); the
  /// ATmega2560 takes 3.4 ms (datasheet, EEPROM programming time). This keeps EEPE set that long
  /// after each write, so avr-libc's eeprom_write_byte waits as on the chip (a 570-byte
  /// save_eeprom: ~2 s). Hooks the EECR write (chained after simavr's own handler).
  void TimeWrites();
  bool ok() const { return file_.ok(); }
  uint64_t writes() const { return writes_; }
  void CountWrite() { ++writes_; }

 private:
  avr_t* avr_;
  board::SettingsFile file_;
  uint8_t* live_ = nullptr;  // simavr's EEPROM bytes (kSize)
  uint64_t writes_ = 0;
};

}  // namespace avrboard
}  // namespace ja
