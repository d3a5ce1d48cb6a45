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
// The line itself (serial faults, the bounded wire, the host's bytes, the cut between frames) is
// board_common's UartLine, which a board in another language reaches through ja_sim_board.h.
// Bytes the pty does not take wait on its wire (bounded); with --fast the board waits for the host
// (Blocked()), in real time what does not fit is dropped and counted (a USB bridge's full buffer).
#pragma once

#include <stdint.h>

#include <cstdio>
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
  UartLink(avr_t* avr, const board::CommonOptions& line, const LinkOptions& opt, board::Pty& pty);
  ~UartLink();
  /// Hooks USART0. False if the core has none.
  bool Attach();
  /// After every instruction batch: line rate, receive pacing, pty output.
  void Service();
  /// Reads what the host sent (non-blocking).
  void Receive() { line_.Receive(); }
  /// Bytes wait for the host (the pty is full).
  bool Blocked() const { return line_.Blocked(); }
  void Disconnected() { line_.Disconnected(); }
  /// The cable is to be pulled: at the end of the frame on the line (after its 0x00 delimiter,
  /// bytes after it no longer reach the wire), or at once when the line has been idle for
  /// `idle_cycles`. CutReady() tells when.
  void ArmCut(uint64_t idle_cycles);
  bool CutReady() const { return line_.CutReady(); }
  /// Writes what waits to the pty.
  void Flush() { line_.Flush(); }

  double baud() const { return baud_; }
  uint64_t tx_bytes() const { return line_.tx_bytes(); }
  uint64_t rx_bytes() const { return rx_bytes_; }
  uint64_t bridge_dropped() const { return line_.bridge_dropped(); }
  uint64_t dropped() const { return line_.dropped(); }
  uint64_t corrupted() const { return line_.corrupted(); }

 private:
  static void OnOutput(avr_irq_t* irq, uint32_t value, void* param);
  void Transmit(uint8_t b);
  void SetLineRate();

  avr_t* avr_;
  const uint32_t line_baud_;  // --baud, 0: the firmware's
  const LinkOptions& opt_;
  board::UartLine line_;
  avr_uart_t* uart_ = nullptr;
  avr_irq_t* input_ = nullptr;
  uint64_t cycles_per_byte_ = 0;  // what the link set (10 bits per byte)
  uint64_t next_rx_ = 0;
  double baud_ = 0;
  FILE* log_ = nullptr;
  uint64_t rx_bytes_ = 0;
};

}  // namespace avrboard
}  // namespace ja
