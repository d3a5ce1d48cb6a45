// The RP2040's second-stage boot (boot2) for any SPI NOR flash: the flash's plain 03h read.
//
// The bootrom reads the first 256 bytes of flash into the top of SRAM (0x20041F00), checks the
// CRC-32 in their last 4 bytes (firmware/tools/pico_boot2.py appends it) and runs them. This
// code sets up the XIP_SSI so that flash appears at 0x10000000 (execute in place), then enters
// the image through its vector table at 0x10000100. It is position independent (PC-relative
// literals only): the same bytes run wherever they are copied.
//
// The XIP_SSI (a Synopsys DW_apb_ssi at 0x18000000), as configured here:
//   CTRLR0     SPI_FRF (bits 22:21) = 0: standard 1-bit SPI; DFS_32 (20:16) = 31: 32-bit data
//              frames; TMOD (9:8) = 3: EEPROM read (command + address out, then data in).
//   CTRLR1     NDF = 0: one data frame per XIP access.
//   BAUDR      SCKDV = 4: SCK = clk_sys / 4 (must be even; clk_sys is the ring oscillator,
//              a few MHz, until the application starts the crystal and PLLs).
//   SPI_CTRLR0 XIP_CMD (31:24) = 0x03; INST_L (9:8) = 2: 8-bit instruction; ADDR_L (5:2) = 6:
//              24-bit address (4-bit units); WAIT_CYCLES (15:11) = 0; TRANS_TYPE (1:0) = 0:
//              command and address both in standard SPI.
// The SSI can only be configured while disabled (SSIENR = 0).
//
// Called from the bootrom, lr is 0: vector into the image (VTOR, MSP, reset handler). Called
// as a function (lr != 0, e.g. to restore XIP after the flash was programmed), it returns.
// It must fit in 252 bytes: the build refuses a longer one (boot2.ld and pico_boot2.py).

    .syntax unified
    .cpu cortex-m0plus
    .thumb

    .equ XIP_SSI_BASE,      0x18000000
    .equ SSI_CTRLR0,        0x00
    .equ SSI_CTRLR1,        0x04
    .equ SSI_SSIENR,        0x08
    .equ SSI_BAUDR,         0x14
    .equ SSI_SPI_CTRLR0,    0xF4   // beyond str's immediate offset range (124): register offset

    .equ CTRLR0_XIP,        (0 << 21) | (31 << 16) | (3 << 8)
    .equ SPI_CTRLR0_XIP,    (0x03 << 24) | (2 << 8) | (6 << 2) | 0
    .equ SCK_DIVIDER,       4

    .equ IMAGE_VECTORS,     0x10000100   // the image's vector table, right after boot2
    .equ M0PLUS_VTOR,       0xE000ED08   // Cortex-M0+ vector table offset register

    .section .text.boot2, "ax"
    .global ja_boot2
    .type ja_boot2, %function
ja_boot2:
    push {lr}
    ldr r3, =XIP_SSI_BASE
    movs r0, #0
    str r0, [r3, #SSI_SSIENR]          // disable the SSI to configure it
    movs r0, #SCK_DIVIDER
    str r0, [r3, #SSI_BAUDR]
    ldr r0, =CTRLR0_XIP
    str r0, [r3, #SSI_CTRLR0]
    ldr r0, =SPI_CTRLR0_XIP
    movs r1, #SSI_SPI_CTRLR0
    str r0, [r3, r1]
    movs r0, #0
    str r0, [r3, #SSI_CTRLR1]          // NDF = 0: one 32-bit frame per access
    movs r0, #1
    str r0, [r3, #SSI_SSIENR]          // enable: flash reads now go through XIP
    pop {r0}
    cmp r0, #0
    beq 1f
    bx r0                              // called as a function: return
1:
    ldr r0, =IMAGE_VECTORS
    ldr r1, =M0PLUS_VTOR
    str r0, [r1]                       // exceptions use the image's table
    ldmia r0, {r0, r1}                 // r0 = initial SP, r1 = reset handler (Thumb bit set)
    msr msp, r0
    bx r1
    .size ja_boot2, . - ja_boot2
    .ltorg
