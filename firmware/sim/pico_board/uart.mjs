// UART0 as the RP2040's PL011 behaves on the wire (datasheet 4.2; ARM PL011 TRM), replacing
// rp2040js's model, which sends each byte the instant it is written and always reports an empty
// transmit FIFO. Here a byte takes its frame time at the programmed baud rate (start bit, data
// bits, parity, stop bits from LCR_H; the rate from IBRD/FBRD and clk_peri), the transmit FIFO
// holds 32 bytes (1 with FIFOs off), and the interrupts follow the PL011's rules:
//   - TX: raised when the transmit FIFO drains to its trigger level or below (IFLS), as a
//     transition, not a level: enabling TXIM on an empty FIFO raises nothing, so a driver must
//     prime the FIFO; cleared by filling the FIFO above the level or by ICR.
//   - RX: raised when the receive FIFO reaches its trigger level; RT (receive timeout) when it
//     holds data and no byte arrived for 32 bit periods; both cleared by reading it below the
//     level / empty, or by ICR. A byte arriving at a full FIFO is lost (OE).
// Bytes from the host are clocked in at the same rate, one frame each.
import { BasePeripheral } from 'rp2040js';

const DR = 0x00, RSR = 0x04, FR = 0x18, ILPR = 0x20, IBRD = 0x24, FBRD = 0x28, LCR_H = 0x2c;
const CR = 0x30, IFLS = 0x34, IMSC = 0x38, RIS = 0x3c, MIS = 0x40, ICR = 0x44, DMACR = 0x48;
const FR_BUSY = 1 << 3, FR_RXFE = 1 << 4, FR_TXFF = 1 << 5, FR_RXFF = 1 << 6, FR_TXFE = 1 << 7;
const LCR_PEN = 1 << 1, LCR_STP2 = 1 << 3, LCR_FEN = 1 << 4;
const CR_UARTEN = 1 << 0, CR_TXE = 1 << 8, CR_RXE = 1 << 9;
const INT_RX = 1 << 4, INT_TX = 1 << 5, INT_RT = 1 << 6, INT_OE = 1 << 10;
const DR_OE = 1 << 11;
const FIFO_DEPTH = 32;
const TRIGGER_EIGHTHS = [1, 2, 4, 6, 7]; // IFLS 0..4: 1/8, 1/4, 1/2, 3/4, 7/8 full
// PrimeCell identification (the PL011's own values, TRM 3.3.14-15).
const ID_REGS = { 0xfe0: 0x11, 0xfe4: 0x10, 0xfe8: 0x34, 0xfec: 0x00,
                  0xff0: 0x0d, 0xff4: 0xf0, 0xff8: 0x05, 0xffc: 0xb1 };

export class PacedUart extends BasePeripheral {
  /** `irq`: the NVIC line; `onWire(byte)` receives each byte as its stop bit ends. */
  constructor(rp2040, name, irq, onWire) {
    super(rp2040, name);
    this.irq = irq;
    this.onWire = onWire;
    this.clock = rp2040.clock;
    this.cr = CR_RXE | CR_TXE;
    this.lcrH = 0;
    this.ibrd = 0;
    this.fbrd = 0;
    this.ifls = 0x12; // reset: both at 1/2
    this.imsc = 0;
    this.ris = 0;
    this.tx = [];
    this.shifting = false; // a byte in the transmit shift register
    this.rx = [];
    this.rxWaiting = []; // host bytes not yet clocked in
    this.rxClocking = false;
    this.overruns = 0;
    this.txAlarm = this.clock.createAlarm(() => this.txFrameDone());
    this.rxAlarm = this.clock.createAlarm(() => this.rxFrameDone());
    this.rtAlarm = this.clock.createAlarm(() => this.rxTimeout());
    this.shiftByte = 0;
  }

  get fifoDepth() { return this.lcrH & LCR_FEN ? FIFO_DEPTH : 1; }
  get divisor() { return this.ibrd + this.fbrd / 64; }
  /** The line rate the registers give (0 until the divisor is set). */
  get baud() { return this.divisor ? this.rp2040.clkPeri / (16 * this.divisor) : 0; }
  get frameBits() {
    return 1 + (5 + ((this.lcrH >> 5) & 3)) + (this.lcrH & LCR_PEN ? 1 : 0)
        + (this.lcrH & LCR_STP2 ? 2 : 1);
  }
  /** One frame on the line, ns (the line may be re-timed by the harness: lineBaud). */
  frameNs() {
    const baud = this.lineBaud || this.baud;
    return baud ? (this.frameBits * 1e9) / baud : 1e9;
  }
  txTrigger() { return (TRIGGER_EIGHTHS[this.ifls & 7] ?? 4) * FIFO_DEPTH / 8; }
  rxTrigger() { return (TRIGGER_EIGHTHS[(this.ifls >> 3) & 7] ?? 4) * FIFO_DEPTH / 8; }
  get enabled() { return (this.cr & CR_UARTEN) !== 0; }

  update() { this.rp2040.setInterrupt(this.irq, (this.ris & this.imsc) !== 0); }

  // ---- transmit ----
  pushTx(byte) {
    if (this.tx.length >= this.fifoDepth) return; // written to a full FIFO: lost (as on the chip)
    this.tx.push(byte);
    const above = this.lcrH & LCR_FEN ? this.tx.length > this.txTrigger() : true;
    if (above && this.ris & INT_TX) { this.ris &= ~INT_TX; this.update(); }
    this.startTx();
  }
  startTx() {
    if (this.shifting || !this.tx.length || !this.enabled || !(this.cr & CR_TXE)) return;
    this.shiftByte = this.tx.shift();
    this.shifting = true;
    this.txAlarm.schedule(this.frameNs());
    this.txLevelFell();
  }
  txLevelFell() {
    const level = this.tx.length;
    const fell = this.lcrH & LCR_FEN ? level <= this.txTrigger() && level + 1 > this.txTrigger()
      : level === 0;
    if (fell && !(this.ris & INT_TX)) { this.ris |= INT_TX; this.update(); }
  }
  txFrameDone() {
    this.shifting = false;
    this.onWire(this.shiftByte);
    this.startTx();
  }
  /** Bytes the transmitter still holds (FIFO + shift register). */
  get txPending() { return this.tx.length + (this.shifting ? 1 : 0); }

  // ---- receive ----
  /** A byte from the host: clocked in one frame later (queued behind those still arriving). */
  feed(byte) {
    this.rxWaiting.push(byte);
    if (!this.rxClocking) { this.rxClocking = true; this.rxAlarm.schedule(this.frameNs()); }
  }
  rxFrameDone() {
    const byte = this.rxWaiting.shift();
    if (this.enabled && this.cr & CR_RXE) {
      if (this.rx.length >= this.fifoDepth) {
        this.overruns++;
        this.rx[this.rx.length - 1] |= DR_OE;
        this.ris |= INT_OE;
      } else {
        this.rx.push(byte);
      }
      const level = this.rx.length;
      if (this.lcrH & LCR_FEN ? level >= this.rxTrigger() : level >= 1) this.ris |= INT_RX;
      this.rtAlarm.schedule(32 * this.frameNs() / this.frameBits);
      this.update();
    }
    if (this.rxWaiting.length) this.rxAlarm.schedule(this.frameNs());
    else this.rxClocking = false;
  }
  rxTimeout() {
    if (this.rx.length && !(this.ris & INT_RT)) { this.ris |= INT_RT; this.update(); }
  }
  popRx() {
    if (!this.rx.length) return 0;
    const value = this.rx.shift();
    const level = this.rx.length;
    let changed = false;
    if (this.ris & INT_RX && (this.lcrH & LCR_FEN ? level < this.rxTrigger() : level === 0)) {
      this.ris &= ~INT_RX; changed = true;
    }
    if (this.ris & INT_RT && level === 0) { this.ris &= ~INT_RT; changed = true; }
    if (changed) this.update();
    return value;
  }

  // ---- registers ----
  readUint32(offset) {
    switch (offset) {
      case DR: return this.popRx();
      case RSR: return this.rx.length && this.rx[0] & DR_OE ? 8 : 0;
      case FR:
        return (this.shifting || this.tx.length ? FR_BUSY : 0)
          | (this.rx.length ? 0 : FR_RXFE)
          | (this.rx.length >= this.fifoDepth ? FR_RXFF : 0)
          | (this.tx.length >= this.fifoDepth ? FR_TXFF : 0)
          | (this.tx.length ? 0 : FR_TXFE);
      case ILPR: return 0;
      case IBRD: return this.ibrd;
      case FBRD: return this.fbrd;
      case LCR_H: return this.lcrH;
      case CR: return this.cr;
      case IFLS: return this.ifls;
      case IMSC: return this.imsc;
      case RIS: return this.ris;
      case MIS: return this.ris & this.imsc;
      case DMACR: return 0;
    }
    if (offset in ID_REGS) return ID_REGS[offset];
    return super.readUint32(offset);
  }

  writeUint32(offset, value) {
    switch (offset) {
      case DR: this.pushTx(value & 0xff); return;
      case RSR: return; // error clear
      case ILPR: return;
      case IBRD: this.ibrd = value & 0xffff; return;
      case FBRD: this.fbrd = value & 0x3f; return;
      case LCR_H: this.lcrH = value & 0xff; return; // (also latches IBRD/FBRD on the chip)
      case CR: this.cr = value & 0xff87; this.startTx(); return;
      case IFLS: this.ifls = value & 0x3f; return;
      case IMSC: this.imsc = value & 0x7ff; this.update(); return;
      case ICR: this.ris &= ~(value & 0x7ff); this.update(); return;
      case DMACR: return;
    }
    super.writeUint32(offset, value);
  }
}
