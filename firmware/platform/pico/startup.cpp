// Start-up of the jointangle image on the RP2040's Cortex-M0+ (core 0): the vector table and the
// reset handler. boot2 (boot2_generic_03h.S) points VTOR at the table (0x10000100, memmap.ld),
// loads the stack pointer from its first word and jumps to its second, ja_reset_handler.
//
// Every handler but the reset handler is a weak alias of ja_default_handler: a driver defines
// the real one under the same name (e.g. `extern "C" void isr_timer_0()`) and the linker takes
// it. The RP2040's 26 interrupts (datasheet "Interrupts"): TIMER_IRQ_0..3, PWM_IRQ_WRAP,
// USBCTRL_IRQ, XIP_IRQ, PIO0_IRQ_0..1, PIO1_IRQ_0..1, DMA_IRQ_0..1, IO_IRQ_BANK0, IO_IRQ_QSPI,
// SIO_IRQ_PROC0..1, CLOCKS_IRQ, SPI0_IRQ, SPI1_IRQ, UART0_IRQ, UART1_IRQ, ADC_IRQ_FIFO, I2C0_IRQ,
// I2C1_IRQ, RTC_IRQ.
#include <stdint.h>

extern "C" {
// From memmap.ld.
extern uint32_t __data_load_start__[], __data_start__[], __data_end__[];
extern uint32_t __bss_start__[], __bss_end__[];
extern uint32_t __stack_top__[];
using Constructor = void (*)();
extern Constructor __init_array_start[], __init_array_end[];

int main();

[[noreturn]] void ja_reset_handler();
void ja_default_handler();

#define JA_WEAK_HANDLER(name) void name() __attribute__((weak, alias("ja_default_handler")))
JA_WEAK_HANDLER(isr_nmi);
JA_WEAK_HANDLER(isr_hardfault);
JA_WEAK_HANDLER(isr_svcall);
JA_WEAK_HANDLER(isr_pendsv);
JA_WEAK_HANDLER(isr_systick);
JA_WEAK_HANDLER(isr_timer_0);
JA_WEAK_HANDLER(isr_timer_1);
JA_WEAK_HANDLER(isr_timer_2);
JA_WEAK_HANDLER(isr_timer_3);
JA_WEAK_HANDLER(isr_pwm_wrap);
JA_WEAK_HANDLER(isr_usbctrl);
JA_WEAK_HANDLER(isr_xip);
JA_WEAK_HANDLER(isr_pio0_0);
JA_WEAK_HANDLER(isr_pio0_1);
JA_WEAK_HANDLER(isr_pio1_0);
JA_WEAK_HANDLER(isr_pio1_1);
JA_WEAK_HANDLER(isr_dma_0);
JA_WEAK_HANDLER(isr_dma_1);
JA_WEAK_HANDLER(isr_io_bank0);
JA_WEAK_HANDLER(isr_io_qspi);
JA_WEAK_HANDLER(isr_sio_proc0);
JA_WEAK_HANDLER(isr_sio_proc1);
JA_WEAK_HANDLER(isr_clocks);
JA_WEAK_HANDLER(isr_spi0);
JA_WEAK_HANDLER(isr_spi1);
JA_WEAK_HANDLER(isr_uart0);
JA_WEAK_HANDLER(isr_uart1);
JA_WEAK_HANDLER(isr_adc_fifo);
JA_WEAK_HANDLER(isr_i2c0);
JA_WEAK_HANDLER(isr_i2c1);
JA_WEAK_HANDLER(isr_rtc);
#undef JA_WEAK_HANDLER
}

namespace {

using Handler = void (*)();
constexpr int kSystemVectors = 16;  // initial SP, then the Cortex-M0+ exceptions 1..15
constexpr int kIrqVectors = 26;     // RP2040 IRQ 0..25

struct VectorTable {
  uint32_t* initial_sp;
  Handler system[kSystemVectors - 1];  // exceptions 1..15; reserved entries are null
  Handler irq[kIrqVectors];
};

}  // namespace

// Placed at 0x10000100 by memmap.ld (section .vectors, kept although nothing refers to it).
extern "C" __attribute__((section(".vectors"), used)) const VectorTable ja_vector_table = {
    __stack_top__,
    {
        ja_reset_handler,  //  1 Reset
        isr_nmi,           //  2 NMI
        isr_hardfault,     //  3 HardFault
        nullptr,           //  4-10 reserved on ARMv6-M
        nullptr, nullptr, nullptr, nullptr, nullptr, nullptr,
        isr_svcall,  // 11 SVCall
        nullptr,     // 12-13 reserved
        nullptr,
        isr_pendsv,   // 14 PendSV
        isr_systick,  // 15 SysTick
    },
    {
        isr_timer_0, isr_timer_1,  isr_timer_2, isr_timer_3,   isr_pwm_wrap,  isr_usbctrl,
        isr_xip,     isr_pio0_0,   isr_pio0_1,  isr_pio1_0,    isr_pio1_1,    isr_dma_0,
        isr_dma_1,   isr_io_bank0, isr_io_qspi, isr_sio_proc0, isr_sio_proc1, isr_clocks,
        isr_spi0,    isr_spi1,     isr_uart0,   isr_uart1,     isr_adc_fifo,  isr_i2c0,
        isr_i2c1,    isr_rtc,
    },
};
static_assert(sizeof(VectorTable) == (kSystemVectors + kIrqVectors) * 4,
              "the vector table is 42 words");

/// Runs from flash with the stack boot2 set: initialises RAM, runs the C++ static constructors,
/// then main(); if main returns, waits here for the watchdog or a debugger.
extern "C" void ja_reset_handler() {
  const uint32_t* from = __data_load_start__;
  for (uint32_t* to = __data_start__; to < __data_end__;) *to++ = *from++;
  for (uint32_t* p = __bss_start__; p < __bss_end__;) *p++ = 0;
  for (Constructor* c = __init_array_start; c < __init_array_end; ++c) (*c)();
  main();
  for (;;) {
    __asm volatile("" ::: "memory");
  }
}

/// Any exception or interrupt without a handler of its own: stop here (a debugger shows which
/// one in IPSR). The watchdog, once a later session starts it, then resets the chip.
extern "C" void ja_default_handler() {
  for (;;) {
    __asm volatile("" ::: "memory");
  }
}
