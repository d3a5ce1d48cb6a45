// The app's settings store (app::Eeprom) in the last 4 KB sector of the Pico's 2 MB flash
// (offset 0x1FF000; memmap.ld keeps the image out of it). Reads come straight from the XIP
// window. Writes are staged in a RAM copy of the sector; Commit() erases the sector and programs
// the copy through the bootrom's flash functions (datasheet 2.8.3.1.3, found through the ROM
// table: connect_internal_flash 'IF', flash_exit_xip 'EX', flash_range_erase 'RE',
// flash_range_program 'RP', flash_flush_cache 'FC'), then calls the copy of boot2 in RAM to
// bring XIP back (boot2_generic_03h.S returns when called as a function). While XIP is off
// nothing may run from flash: that sequence is one function in RAM (.time_critical), run with
// interrupts off (the vector table and every handler are in flash). A sector erase takes up to
// 400 ms on a W25Q16JV: the watchdog gets 2 s for it.
#pragma once

#include <stdint.h>

#include "app/hal.hpp"
#include "platform/pico/board/rp2040.hpp"

namespace ja {
namespace pico {

class FlashEeprom final : public app::Eeprom {
 public:
  static constexpr uint32_t kOffset = hw::kFlashBytes - hw::kFlashSectorBytes;  // 0x1FF000
  static constexpr uint32_t kCommitWatchdogMs = 2000;

  /// Finds the bootrom's flash functions and copies boot2 to RAM (while XIP runs).
  void Init();
  uint16_t Size() override { return hw::kFlashSectorBytes; }
  uint8_t Read(uint16_t addr) override;
  void Write(uint16_t addr, uint8_t value) override;
  /// Erases and programs the sector when a write changed it; false when the bootrom has no
  /// flash functions (the app's read-back then fails: eeprom_failed).
  bool Commit() override;
};

}  // namespace pico
}  // namespace ja
