// A transmit buffer a board can put behind SerialPort: 256 bytes (255 usable), one producer (the
// app: Free/Write) and one consumer (the UART: the AVR's UDRE interrupt, or a thread pacing bytes
// at the baud rate: Pop). One-byte indices, each written by one side only, so the AVR needs no
// interrupt masking. A thread-based consumer on a host must add its own memory ordering (a mutex).
// Size: one 70-byte high-rate frame is 0.7 ms at 1 Mbaud; 255 bytes hold three of them. The
// Arduino core's 64-byte HardwareSerial buffer is too small for the app's whole-frame writes.
#pragma once

#include <stdint.h>

namespace ja {
namespace app {

class TxRing {
 public:
  static constexpr uint16_t kCapacity = 255;

  /// Bytes that can be written now.
  uint16_t Free() const {
    return static_cast<uint16_t>(kCapacity - static_cast<uint8_t>(head_ - tail_));
  }
  /// Bytes waiting to be sent.
  uint16_t Used() const { return static_cast<uint8_t>(head_ - tail_); }
  /// Appends n <= Free() bytes (more are ignored: the app never writes more).
  void Write(const uint8_t* data, uint16_t n) {
    if (n > Free()) return;
    uint8_t h = head_;
    for (uint16_t i = 0; i < n; ++i) buf_[h++] = data[i];
    head_ = h;  // publish after the bytes are stored
  }
  /// The next byte to send; false when empty.
  bool Pop(uint8_t* out) {
    const uint8_t t = tail_;
    if (t == head_) return false;
    *out = buf_[t];
    tail_ = static_cast<uint8_t>(t + 1);
    return true;
  }

 private:
  uint8_t buf_[256];
  volatile uint8_t head_ = 0;  // written by the producer only
  volatile uint8_t tail_ = 0;  // written by the consumer only
};

}  // namespace app
}  // namespace ja
