// A virtual board's settings store kept in a file (the AVR board's 4 KB EEPROM, the Pico board's
// flash sector through ja_sim_board.h), so a reset and a restart of the board both find what the
// firmware saved. A missing or empty file starts as the store of a board fresh from the factory
// with the rig loaded: erased (0xFF) with the rig's configuration written by the application's
// own SaveConfig (app/app_config.hpp), or erased only for an image other than the project's (a
// new chip). An existing file must be an image of the store's size and is used as it is; a file
// of any other size is someone else's and is left untouched. Without a path the file lives in a
// temporary directory removed with the object.
#pragma once

#include <stdint.h>

#include <string>
#include <vector>

#include "app/app_config.hpp"

namespace ja {
namespace board {

class SettingsFile {
 public:
  SettingsFile() = default;
  SettingsFile(const SettingsFile&) = delete;
  SettingsFile& operator=(const SettingsFile&) = delete;
  ~SettingsFile();
  /// Opens (or creates) `path` ("" = $TMPDIR/`tmp_prefix`-XXXXXX/eeprom.bin) as a store of
  /// `size` bytes (1..65535, app::Eeprom's address range) and writes the starting image to it
  /// (above). False with *error naming the file when it cannot, or when the file has another size.
  bool Open(const std::string& path, uint32_t size, const app::Config& cfg, bool erased,
            const char* tmp_prefix, std::string* error);
  /// The image as last written to the file (`size` bytes; empty before Open).
  const std::vector<uint8_t>& image() const { return saved_; }
  /// Writes the bytes of `now` (the store as the firmware left it, `size` bytes) that differ from
  /// image() to the file. Returns how many bytes changed; a failed write clears ok().
  uint32_t Persist(const uint8_t* now);
  const std::string& path() const { return path_; }
  bool is_open() const { return fd_ >= 0; }
  /// No write to the file has failed.
  bool ok() const { return ok_; }

 private:
  int fd_ = -1;
  std::vector<uint8_t> saved_;
  std::string tmpdir_, path_;
  bool ok_ = true;
};

}  // namespace board
}  // namespace ja
