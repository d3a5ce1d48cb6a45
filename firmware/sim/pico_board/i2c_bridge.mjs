// I2C0 of the emulated RP2040 on the virtual bus (libja_sim_devices): rp2040js's DW_apb_i2c
// model asks at each bus event (START, address, data byte written or read, STOP) and waits until
// the harness completes it. Each event takes its time at the SCL rate the firmware programmed:
// the DW_apb_i2c's fast-mode SCL high period is IC_FS_SCL_HCNT + IC_FS_SPKLEN + 7 ic_clk cycles,
// low IC_FS_SCL_LCNT + 1 (ic_clk = clk_sys on the RP2040; standard mode with the SS counts);
// START and STOP take one SCL period, a byte and its ACK nine. The device sees a written byte
// when its ACK is clocked and is asked for a read byte when the byte starts, at the emulator's
// time (+ the board's time base across resets). A clock-stretching slave holds SCL after
// acknowledging a read address (--clock-stretch).
import { I2CSpeed } from 'rp2040js';

export class I2cBridge {
  constructor(i2c, sim, api, deviceNs, stretchUs, stats) {
    this.i2c = i2c;
    this.sim = sim;
    this.api = api;
    this.deviceNs = deviceNs;
    this.stretchUs = stretchUs; // Map addr7 -> µs
    this.clock = i2c.rp2040.clock;
    this.pending = null;
    this.alarm = this.clock.createAlarm(() => this.fire());
    this.stats = stats; // {busyNs}: the bus's time in transfers, across chip resets
    patchRegisters(i2c);
    i2c.onStart = () => this.after(1, () => { this.at(); api.busStart(sim); i2c.completeStart(); });
    i2c.onConnect = (addr, mode) => this.after(9, () => {
      this.at();
      const ack = api.busWriteByte(sim, ((addr & 0x7f) << 1) | mode) === 1;
      const hold = ack && mode === 1 ? (this.stretchUs.get(addr & 0x7f) ?? 0) * 1000 : 0;
      if (hold) { this.stats.busyNs += hold; this.afterNs(hold, () => i2c.completeConnect(true)); }
      else i2c.completeConnect(ack);
    });
    i2c.onWriteByte = (value) => this.after(9, () => {
      this.at();
      i2c.completeWrite(api.busWriteByte(sim, value & 0xff) === 1);
    });
    i2c.onReadByte = (ack) => {
      this.at();
      const value = api.busReadByte(sim, ack ? 1 : 0) & 0xff;
      this.after(9, () => i2c.completeRead(value));
    };
    i2c.onStop = () => this.after(1, () => { this.at(); api.busStop(sim); i2c.completeStop(); });
  }

  /** One SCL period in ns at the rate the registers program. */
  sclPeriodNs() {
    const i = this.i2c;
    const standard = i.speed === I2CSpeed.Standard;
    const high = (standard ? i.ssClockHighPeriod : i.fsClockHighPeriod) + i.spikelen + 7;
    const low = (standard ? i.ssClockLowPeriod : i.fsClockLowPeriod) + 1;
    return ((high + low) * 1e9) / i.rp2040.clkSys;
  }
  at() { this.api.setTimeNs(this.sim, this.deviceNs()); }
  after(bits, then) {
    const ns = bits * this.sclPeriodNs();
    this.stats.busyNs += ns;
    this.afterNs(ns, then);
  }
  afterNs(ns, then) {
    this.pending = then;
    this.alarm.schedule(ns);
  }
  fire() {
    const then = this.pending;
    this.pending = null;
    if (then) then();
  }
}

const IC_INTR_MASK = 0x30;
const IC_SDA_HOLD = 0x7c;
const IC_FS_SPKLEN = 0xa0;

/** What rp2040js 1.4.1's DW_apb_i2c model gets wrong, as the RP2040 datasheet (4.3.17) has it:
 * IC_INTR_MASK writes are ignored (no interrupt could ever fire), IC_FS_SPKLEN takes only even
 * values (it tests the value against the ENABLE bit), IC_SDA_HOLD is not stored. */
function patchRegisters(i2c) {
  const write = i2c.writeUint32.bind(i2c);
  const read = i2c.readUint32.bind(i2c);
  let sdaHold = 1;
  i2c.writeUint32 = (offset, value) => {
    if (offset === IC_INTR_MASK) {
      i2c.intEnable = value & 0x1fff;
      i2c.checkInterrupts();
    } else if (offset === IC_FS_SPKLEN) {
      if (!(i2c.enable & 1)) i2c.spikelen = Math.max(1, value & 0xff);
    } else if (offset === IC_SDA_HOLD) {
      sdaHold = value & 0xffffff;
    } else {
      write(offset, value);
    }
  };
  i2c.readUint32 = (offset) => (offset === IC_SDA_HOLD ? sdaHold : read(offset));
}
