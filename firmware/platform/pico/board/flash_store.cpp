#include "platform/pico/board/flash_store.hpp"

#include <stddef.h>
#include <string.h>

#include "platform/pico/board/chip.hpp"

// From memmap.ld: boot2's 256 bytes at the start of flash.
extern "C" uint32_t __boot2_start__[];

namespace ja {
namespace pico {

namespace {

using namespace hw;

// The bootrom's ROM table (datasheet 2.8.3): 'M' 'u' 0x01 at 0x10, then 16-bit pointers: the
// function table at 0x14 and rom_table_lookup(table, code) at 0x18 (Thumb bit set).
constexpr uint32_t kRomMagicAddr = 0x10;
constexpr uint32_t kRomFuncTableAddr = 0x14;
constexpr uint32_t kRomTableLookupAddr = 0x18;
constexpr uint32_t kRomMagicMask = 0x00FFFFFF;
constexpr uint32_t kRomMagic = 'M' | ('u' << 8) | (0x01 << 16);
constexpr uint32_t RomCode(char a, char b) {
  return static_cast<uint8_t>(a) | (static_cast<uint32_t>(static_cast<uint8_t>(b)) << 8);
}
// flash_range_erase's block command: 0x20 (sector erase, 4 KB), one sector of one block.
constexpr uint32_t kEraseBlockBytes = kFlashSectorBytes;
constexpr uint8_t kEraseSectorCmd = 0x20;

struct FlashRom {
  void (*connect_internal_flash)();
  void (*flash_exit_xip)();
  void (*flash_range_erase)(uint32_t addr, size_t count, uint32_t block_size, uint8_t cmd);
  void (*flash_range_program)(uint32_t addr, const uint8_t* data, size_t count);
  void (*flash_flush_cache)();
  void (*enter_xip)();  // the RAM copy of boot2
};

FlashRom g_rom = {};
bool g_rom_found = false;
uint32_t g_boot2_copy[64];                                        // boot2, run from RAM
uint8_t g_sector[kFlashSectorBytes] __attribute__((aligned(4)));  // the staged sector
bool g_staged = false;                                            // g_sector holds pending writes

/// A 16-bit word of the bootrom (the address laundered through an asm so the compiler does not
/// treat a small constant address as a null-pointer access).
uint32_t RomHword(uint32_t addr) {
  __asm volatile("" : "+r"(addr));
  return *reinterpret_cast<const volatile uint16_t*>(addr);
}

void* RomFunc(uint32_t code) {
  using Lookup = void* (*)(const uint16_t* table, uint32_t code);
  const auto lookup = reinterpret_cast<Lookup>(RomHword(kRomTableLookupAddr));
  const auto* table = reinterpret_cast<const uint16_t*>(RomHword(kRomFuncTableAddr));
  return lookup(table, code);
}

const volatile uint8_t* SectorInFlash() {
  return reinterpret_cast<const volatile uint8_t*>(kXipBase + FlashEeprom::kOffset);
}

/// Runs from RAM (memmap.ld copies .time_critical with .data), interrupts off: nothing here
/// may touch flash (no call into .text, no literal in .rodata), XIP being off from
/// flash_exit_xip until boot2 has run again. A long call: flash is out of a BL's reach.
__attribute__((noinline, long_call, section(".time_critical.ja_flash_commit"))) void FlashCommit(
    const FlashRom* rom, uint32_t offset, const uint8_t* data) {
  rom->connect_internal_flash();
  rom->flash_exit_xip();
  rom->flash_range_erase(offset, kFlashSectorBytes, kEraseBlockBytes, kEraseSectorCmd);
  rom->flash_range_program(offset, data, kFlashSectorBytes);
  rom->flash_flush_cache();  // also ends the chip-select override connect left
  rom->enter_xip();
}

}  // namespace

void FlashEeprom::Init() {
  memcpy(g_boot2_copy, __boot2_start__, sizeof(g_boot2_copy));
  const uint32_t magic = (RomHword(kRomMagicAddr) | (RomHword(kRomMagicAddr + 2) << 16));
  if ((magic & kRomMagicMask) != kRomMagic) return;
  g_rom.connect_internal_flash = reinterpret_cast<void (*)()>(RomFunc(RomCode('I', 'F')));
  g_rom.flash_exit_xip = reinterpret_cast<void (*)()>(RomFunc(RomCode('E', 'X')));
  g_rom.flash_range_erase =
      reinterpret_cast<decltype(g_rom.flash_range_erase)>(RomFunc(RomCode('R', 'E')));
  g_rom.flash_range_program =
      reinterpret_cast<decltype(g_rom.flash_range_program)>(RomFunc(RomCode('R', 'P')));
  g_rom.flash_flush_cache = reinterpret_cast<void (*)()>(RomFunc(RomCode('F', 'C')));
  g_rom.enter_xip = reinterpret_cast<void (*)()>(reinterpret_cast<uintptr_t>(g_boot2_copy) | 1u);
  g_rom_found = g_rom.connect_internal_flash && g_rom.flash_exit_xip && g_rom.flash_range_erase &&
                g_rom.flash_range_program && g_rom.flash_flush_cache;
}

uint8_t FlashEeprom::Read(uint16_t addr) {
  return addr < kFlashSectorBytes ? SectorInFlash()[addr] : 0xFF;
}

void FlashEeprom::Write(uint16_t addr, uint8_t value) {
  if (addr >= kFlashSectorBytes) return;
  if (!g_staged) {
    for (uint32_t i = 0; i < kFlashSectorBytes; ++i) g_sector[i] = SectorInFlash()[i];
    g_staged = true;
  }
  g_sector[addr] = value;
}

bool FlashEeprom::Commit() {
  if (!g_staged) return true;
  g_staged = false;
  bool changed = false;
  for (uint32_t i = 0; i < kFlashSectorBytes && !changed; ++i) {
    changed = g_sector[i] != SectorInFlash()[i];
  }
  if (!changed) return true;  // nothing to erase: spares the flash a cycle
  if (!g_rom_found) return false;
  WatchdogKickFor(kCommitWatchdogMs);
  const uint32_t primask = SaveAndDisableInterrupts();
  FlashCommit(&g_rom, kOffset, g_sector);
  RestoreInterrupts(primask);
  WatchdogKick();
  return true;
}

}  // namespace pico
}  // namespace ja
