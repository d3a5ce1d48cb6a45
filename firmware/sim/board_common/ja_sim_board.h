/* C ABI over what the virtual boards share (firmware/sim/board_common), so a board written in any
 * language (the Pico board's Node harness, firmware/sim/pico_board) behaves as the two C++ boards
 * (ja_native_board, ja_avr_board) do: the common options, the rig and motion on the virtual
 * devices, the --fault schedule, the settings file, and the pty line with its serial faults and
 * the cable pulled between frames. libja_sim_board.so (Linux); the devices stay in
 * libja_sim_devices.so, on which it depends: the ja_sim* it hands out is for the ja_sim_* calls
 * of ja_sim_devices.h. README.md beside this file says what each call does and why.
 *
 * Every function is safe on a NULL handle (it fails: JA_SIM_EINVAL, 0 or ""). Failures say why in
 * ja_sim_board_last_error. Messages meant for a person (the usage, a --fault switching on or off)
 * go to stderr, prefixed with the board's name (argv[0]); the launcher contract's lines (`PTY
 * <path>`, `DISCONNECTED`) go to stdout, flushed. Not thread-safe: one caller per handle. Times:
 * t_ns is the board's simulated time (never going back), wall times are real time. */
#ifndef JA_SIM_BOARD_H
#define JA_SIM_BOARD_H

#include <stddef.h>
#include <stdint.h>

#include "sim/devices/ja_sim_devices.h" /* ja_sim, JA_SIM_OK, JA_SIM_EINVAL */

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define JA_SIM_BOARD_API __attribute__((visibility("default")))
#else
#define JA_SIM_BOARD_API
#endif

#define JA_SIM_BOARD_ABI_VERSION 1u

typedef struct ja_sim_board ja_sim_board;

/* ja_sim_board_settings_open flags: a new file starts erased (0xFF) instead of holding the rig's
 * configuration (an image other than the project's: a new chip). */
#define JA_SIM_BOARD_SETTINGS_ERASED 1u

/* ja_sim_board_line_service results. */
enum { JA_SIM_BOARD_LINE_PULLED = 1, JA_SIM_BOARD_LINE_RECONNECTED = 2 };

/* Bytes the pty has not taken yet that make the line "blocked": a board running --fast stops its
 * simulated time while ja_sim_board_line_waiting() >= this (the host is behind); in real time at
 * twice this the bytes the UART sends are dropped and counted (bridge_dropped: a USB bridge's full
 * buffer). */
#define JA_SIM_BOARD_WIRE_MAX 4096u

typedef struct ja_sim_board_line_counters {
  uint64_t tx_bytes;       /* bytes the UART sent (ja_sim_board_line_put) */
  uint64_t rx_bytes;       /* bytes of the host the UART took (ja_sim_board_line_take) */
  uint64_t dropped;        /* --drop-every */
  uint64_t corrupted;      /* --corrupt-every */
  uint64_t bridge_dropped; /* lost because the host did not read */
  uint64_t disconnects;    /* cable pulls */
} ja_sim_board_line_counters;

JA_SIM_BOARD_API uint32_t ja_sim_board_abi_version(void);

/* ---- Open and close. ---- */
/* Parses the common options from argv[1..argc) (argv[0]: the board's name, the prefix of its
 * messages; the caller removes its own options first), loads the rig and the motion into a new
 * ja_sim (with --cold-start the BNO055s boot; --loop-motion wraps) and binds the --fault sensors.
 * NULL on failure: an unknown argument or a missing or malformed value prints what is wrong, then
 * the common usage followed by `board_usage` (the board's own options: lines starting with two
 * spaces, each ending in \n; NULL for none) on stderr; a rig, motion or --fault the board cannot
 * use prints its reason. ja_sim_board_last_error(NULL) then says why. */
JA_SIM_BOARD_API ja_sim_board* ja_sim_board_open(int argc, const char* const* argv,
                                                 const char* board_usage);
/* Writes what waits on the wire to the pty, closes it (removing the --link symlink), removes a
 * temporary settings file and destroys the ja_sim. */
JA_SIM_BOARD_API void ja_sim_board_close(ja_sim_board* b);
/* Why the last failing call on b failed ("" if none); with b NULL, why the last
 * ja_sim_board_open on this thread failed. */
JA_SIM_BOARD_API const char* ja_sim_board_last_error(const ja_sim_board* b);

/* ---- The options and the rig. ---- */
/* The virtual devices (owned by b: valid until ja_sim_board_close). */
JA_SIM_BOARD_API ja_sim* ja_sim_board_sim(const ja_sim_board* b);
/* --baud (0: not given, the board's default). */
JA_SIM_BOARD_API uint32_t ja_sim_board_baud(const ja_sim_board* b);
/* --fast, --loop-motion, --cold-start: 1 given, 0 not. */
JA_SIM_BOARD_API int ja_sim_board_fast(const ja_sim_board* b);
JA_SIM_BOARD_API int ja_sim_board_loop_motion(const ja_sim_board* b);
JA_SIM_BOARD_API int ja_sim_board_cold_start(const ja_sim_board* b);
/* --disconnect-after (simulated s), --reconnect-after (wall s): -1 when not given. */
JA_SIM_BOARD_API double ja_sim_board_disconnect_after_s(const ja_sim_board* b);
JA_SIM_BOARD_API double ja_sim_board_reconnect_after_s(const ja_sim_board* b);
/* --link PATH ("" none). */
JA_SIM_BOARD_API const char* ja_sim_board_link(const ja_sim_board* b);
/* The rig's sample rate (Hz), from its configuration. */
JA_SIM_BOARD_API uint32_t ja_sim_board_rate_hz(const ja_sim_board* b);

/* ---- The settings file (--eeprom FILE: the board's EEPROM or flash sector). ---- */
/* Opens (or creates) the file as a store of `size` bytes (1..65535) and copies its starting image
 * to image[0..size): an existing file of `size` bytes as it is; a new, empty or absent one erased
 * (0xFF) with the rig's configuration written by the application's SaveConfig (unless flags has
 * JA_SIM_BOARD_SETTINGS_ERASED), also written to the file. Without --eeprom the file is in a new
 * temporary directory, removed by ja_sim_board_close. A file of another size is left as it is:
 * JA_SIM_EINVAL, the error naming it. Once per board. */
JA_SIM_BOARD_API int ja_sim_board_settings_open(ja_sim_board* b, uint8_t* image, size_t size,
                                                uint32_t flags);
/* Writes the bytes of image[0..size) (the store as the firmware left it; size as opened) that
 * differ from what the file holds. Returns how many bytes changed, or JA_SIM_EINVAL (not open,
 * another size, a write failed). */
JA_SIM_BOARD_API int ja_sim_board_settings_write(ja_sim_board* b, const uint8_t* image,
                                                 size_t size);
/* The file's path (--eeprom, or the temporary file once opened; "" before). */
JA_SIM_BOARD_API const char* ja_sim_board_settings_path(const ja_sim_board* b);

/* ---- Sensor faults (--fault SENSOR:KIND[=PARAM]@START[-END]). ---- */
/* Switches on and off the faults whose time has come by t_ns (a line on stderr for each). Call it
 * before the firmware starts (a fault @0 is there from power-up) and as simulated time passes. */
JA_SIM_BOARD_API int ja_sim_board_apply_faults(ja_sim_board* b, uint64_t t_ns);

/* ---- The serial line: the board's UART on a pty. ---- */
/* Opens a raw pty (the --link symlink pointed at it) and prints `PTY <path>` on stdout. */
JA_SIM_BOARD_API int ja_sim_board_line_open(ja_sim_board* b);
/* A byte the board's UART sent at simulated time t_ns (the board paces its UART at the baud rate):
 * counted, then through the serial faults onto the wire. Returns 1 when it went on the wire, 0
 * when it did not (dropped by --drop-every, the cable being pulled, no pty, the host not reading),
 * JA_SIM_EINVAL. */
JA_SIM_BOARD_API int ja_sim_board_line_put(ja_sim_board* b, uint8_t byte, uint64_t t_ns);
/* Up to `cap` bytes the host sent, in order, into buf (reads the pty, non-blocking, when fewer
 * than cap wait). Returns how many (0: none), JA_SIM_EINVAL. The board takes them at its own
 * pace: one per byte time while its receive FIFO has room. */
JA_SIM_BOARD_API int ja_sim_board_line_take(ja_sim_board* b, uint8_t* buf, size_t cap);
/* Writes what waits on the wire to the pty, as much as it takes. */
JA_SIM_BOARD_API int ja_sim_board_line_flush(ja_sim_board* b);
/* Bytes on the wire the pty has not taken yet (see JA_SIM_BOARD_WIRE_MAX). */
JA_SIM_BOARD_API size_t ja_sim_board_line_waiting(const ja_sim_board* b);
/* Sleeps up to ns of wall time; a byte from the host, or room in the pty while bytes wait on the
 * wire, ends it early (a real-time board waits here for the wall clock to reach simulated time). */
JA_SIM_BOARD_API int ja_sim_board_line_wait(ja_sim_board* b, uint64_t ns);
/* The cable, at simulated time t_ns (call it every slice, e.g. 0.5 ms simulated, after flushing):
 * with --disconnect-after S, once t_ns >= S the cable comes out between frames, after the 0x00
 * delimiter of the frame on the line or at once when the UART has sent nothing for 1 ms
 * simulated; then, blocking up to 2 s, the host reads what was sent (until the wire and the pty
 * have been empty for 100 ms), `DISCONNECTED` is printed and the pty closes; what the host sent
 * and the board has not taken is lost. With --reconnect-after R a new pty opens R wall seconds
 * later (`PTY <path>`). Returns 0, JA_SIM_BOARD_LINE_PULLED (the cable came out in this call),
 * JA_SIM_BOARD_LINE_RECONNECTED (a new pty), JA_SIM_EINVAL (the new pty failed: the board
 * ends, as the C++ boards do with status 1). */
JA_SIM_BOARD_API int ja_sim_board_line_service(ja_sim_board* b, uint64_t t_ns);
/* 1 while a pty is open, else 0. */
JA_SIM_BOARD_API int ja_sim_board_line_connected(const ja_sim_board* b);
/* The open pty's path ("" when none). */
JA_SIM_BOARD_API const char* ja_sim_board_line_path(const ja_sim_board* b);
/* size = sizeof the struct the caller has (layout check). */
JA_SIM_BOARD_API int ja_sim_board_line_get_counters(const ja_sim_board* b,
                                                    ja_sim_board_line_counters* out, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* JA_SIM_BOARD_H */
