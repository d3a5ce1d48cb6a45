// USART0 of the simulated ATmega2560 <-> a pseudo-terminal, paced at the baud rate in simulated
// time, with the serial faults both boards share (--corrupt-every, --drop-every: the pty, the wire
// and the faults are firmware/sim/board_common/serial_line.hpp).
//
// Transmit: simavr raises UART_IRQ_OUTPUT when the firmware writes UDR0 and holds UDRE/TXC for
// `cycles_per_byte`, so the AVR itself paces what it sends. simavr 1.6 charges 11 bits per byte
// (it always counts a parity bit, docs/sensors.md §D2); the link sets `cycles_per_byte` to the 10
// bits of 8N1 at the line rate: cycles = 10 * F_CPU / baud (500 000 baud: 320 cycles = 20 us). The
// line rate is the firmware's own (UBRR0, U2X0: baud = F_CPU / (8 (UBRR+1)) with U2X) unless
// --baud names another one (a deliberately slow line).
// Receive: the host's bytes enter UART_IRQ_INPUT one per byte time, while simavr's receive FIFO
// has room.
// Bytes the pty does not take wait on its wire (bounded); with --fast the board waits for the host
// (Blocked()), in real time what does not fit is dropped and counted (a USB bridge's full buffer).
#pragma once

#include <stdint.h>

#include <cstdio>
#include <deque>
#include <string>

#include "sim/board_common/options.hpp"
#include "sim/board_common/serial_line.hpp"

struct avr_t;
struct avr_irq_t;
struct avr_uart_t;

namespace ja {
namespace avrboard {

// The AVR board's own link options (the line's: board::CommonOptions).
struct LinkOptions {
  std::string uart_log;  // every transmitted byte (before the faults), for benches
  bool pty = true;       // false: no pty (--no-pty: the log only)
};

class UartLink {
 public:
  static constexpr size_t kWireMax = 4096;

  UartLink(avr_t* avr, const board::CommonOptions& line, const LinkOptions& opt, board::Pty& pty);
  ~UartLink();
  /// Hooks USART0. False if the core has none.
  bool Attach();
  /// After every instruction batch: line rate, receive pacing, pty output.
  void Service();
  /// Reads what the host sent (non-blocking).
  void Receive();
  /// Bytes wait for the host (the pty is full).
  bool Blocked() const { return pty_.waiting() >= kWireMax; }
  bool Pending() const { return pty_.waiting() > 0; }
  void Disconnected() { rx_.clear(), cut_armed_ = cut_ready_ = false; }
  /// The cable is to be pulled: at the end of the frame on the line (after its 0x00 delimiter,
  /// bytes after it no longer reach the wire), or at once when the line has been idle for
  /// `idle_cycles`. CutReady() tells when.
  void ArmCut(uint64_t idle_cycles);
  bool CutReady() const { return cut_ready_; }
  /// Writes what waits to the pty.
  void Flush() { pty_.Flush(); }

  double baud() const { return baud_; }
  uint64_t tx_bytes() const { return tx_bytes_; }
  uint64_t rx_bytes() const { return rx_bytes_; }
  uint64_t bridge_dropped() const { return bridge_dropped_; }
  uint64_t dropped() const { return faults_.dropped(); }
  uint64_t corrupted() const { return faults_.corrupted(); }

 private:
  static void OnOutput(avr_irq_t* irq, uint32_t value, void* param);
  void Transmit(uint8_t b);
  void SetLineRate();

  avr_t* avr_;
  const uint32_t line_baud_;  // --baud, 0: the firmware's
  const LinkOptions& opt_;
  board::Pty& pty_;
  board::SerialFaults faults_;
  avr_uart_t* uart_ = nullptr;
  avr_irq_t* input_ = nullptr;
  uint64_t cycles_per_byte_ = 0;  // what the link set (10 bits per byte)
  uint64_t next_rx_ = 0;
  double baud_ = 0;
  std::deque<uint8_t> rx_;
  FILE* log_ = nullptr;
  bool cut_armed_ = false, cut_ready_ = false;
  uint64_t last_tx_cycle_ = 0;
  uint64_t tx_bytes_ = 0, rx_bytes_ = 0, bridge_dropped_ = 0;
};

}  // namespace avrboard
}  // namespace ja
