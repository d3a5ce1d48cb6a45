/* The bootrom of the emulated RP2040 (sim://pico): rp2040js ships none, and the real one is not
 * ours to copy. Only what our image relies on, at the addresses the RP2040 datasheet (2.8
 * "Bootrom") gives them:
 *   0x00  vector table: initial SP, reset, NMI, HardFault;
 *   0x10  'M' 'u' 0x01, version; 0x14 function table, 0x16 data table, 0x18 rom_table_lookup
 *         (16-bit pointers, functions with the Thumb bit);
 *   reset: copy boot2 (flash 0x10000000, 256 bytes) to SRAM 0x20041F00, have its CRC-32 checked,
 *         enter it with lr = 0 (boot2 then vectors into the image, as from the real bootrom).
 * The flash functions keep the real names, codes and signatures; each is `bkpt; bx lr`, and the
 * harness (flash.mjs) does the work at the breakpoint on its model of the QSPI flash. */
  .syntax unified
  .cpu cortex-m0plus
  .thumb
  .section .text
  .global _start
_start:
  .word 0x20042000               /* SP: the top of SCRATCH_Y */
  .word reset + 1
  .word stop + 1                 /* NMI */
  .word stop + 1                 /* HardFault */

  .org 0x10
  .byte 'M', 'u', 0x01, 0x01     /* magic, version */
  .hword func_table
  .hword data_table
  .hword rom_table_lookup + 1
  .hword 0

  .align 2
reset:
  ldr r0, =0x10000000            /* boot2 in flash ... */
  ldr r1, =0x20041F00            /* ... to the top 256 bytes of SCRATCH_X */
  movs r2, #64
copy_word:
  ldr r3, [r0]
  str r3, [r1]
  adds r0, #4
  adds r1, #4
  subs r2, #1
  bne copy_word
  bkpt #0x01                     /* harness: boot2's CRC-32 must match, or the boot stops there */
  movs r0, #0
  mov lr, r0                     /* lr = 0: "entered from the bootrom" */
  ldr r0, =0x20041F01
  bx r0

stop:
  bkpt #0x02                     /* harness: a fault before the image took over */
  b stop

/* void *rom_table_lookup(const uint16_t *table, uint32_t code): entries (code, pointer), 0 ends. */
rom_table_lookup:
  ldrh r2, [r0]
  cmp r2, #0
  beq not_found
  cmp r2, r1
  beq found
  adds r0, #4
  b rom_table_lookup
found:
  ldrh r0, [r0, #2]
  bx lr
not_found:
  movs r0, #0
  bx lr

/* The flash functions (datasheet 2.8.3.1.3): the harness models each at its breakpoint. */
connect_internal_flash:          /* void (void) */
  bkpt #0x10
  bx lr
flash_exit_xip:                  /* void (void) */
  bkpt #0x11
  bx lr
flash_range_erase:               /* void (uint32_t addr, size_t count, uint32_t block_size, uint8_t block_cmd) */
  bkpt #0x12
  bx lr
flash_range_program:             /* void (uint32_t addr, const uint8_t *data, size_t count) */
  bkpt #0x13
  bx lr
flash_flush_cache:               /* void (void) */
  bkpt #0x14
  bx lr
flash_enter_cmd_xip:             /* void (void) */
  bkpt #0x15
  bx lr

  .align 2
func_table:
  .hword 'I' | ('F' << 8), connect_internal_flash + 1
  .hword 'E' | ('X' << 8), flash_exit_xip + 1
  .hword 'R' | ('E' << 8), flash_range_erase + 1
  .hword 'R' | ('P' << 8), flash_range_program + 1
  .hword 'F' | ('C' << 8), flash_flush_cache + 1
  .hword 'C' | ('X' << 8), flash_enter_cmd_xip + 1
  .hword 0, 0
data_table:
  .hword 0, 0
  .ltorg
