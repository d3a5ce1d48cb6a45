// avr_cycles: run an AVR ELF in simavr and report, cycle-exactly, the cycles spent between markers
// the firmware writes to general-purpose I/O registers (see firmware/platform/avr/cycle_marker.h).
//
// Protocol (all three registers are unused by the firmware otherwise):
//   GPIOR0 (data 0x3E) <- id (1..255)  open region `id`: remember avr->cycle
//   GPIOR0 (data 0x3E) <- 0            close the open region: add (cycle - start) to its stats
//   GPIOR2 (data 0x4B) <- byte         console: bytes are collected into lines
//   GPIOR1 (data 0x4A) -> byte         input: the next byte of --input FILE (0 after its end;
//                                      "input_overrun" counts reads past the end)
//   console line "@region <id> <name>" names a region; other lines are reported verbatim.
// The run ends when the firmware sleeps with interrupts off (cpu_Done), crashes, or exceeds
// --max-cycles. Output is one JSON object on stdout. Exit code 0 only when the firmware finished.
//
// Stack high-water mark: before the run the harness paints SRAM from the end of .data+.bss to
// RAMEND with 0xA5 (the C runtime never touches it); afterwards the lowest changed byte bounds
// the deepest stack (and any heap) use: "stack_peak_bytes". A pattern byte pushed by chance
// at the very bottom would under-count by that byte only.
//
// Cycle accounting: simavr adds an instruction's cycles after executing it, so inside the write
// callback avr->cycle is the count before the `out`. A region's raw count is therefore
// 1 (the opening `out`) + the cycles of everything between the two writes; a region named
// "empty" (opened and closed back to back) measures that fixed overhead, and "net" subtracts its
// minimum from every other region.
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sim_avr.h"
#include "sim_elf.h"

enum {
  kMarkerAddr = 0x3E,
  kInputAddr = 0x4A,
  kConsoleAddr = 0x4B,
  kMaxRegions = 256,
  kLineMax = 256,
  kPaint = 0xA5
};

typedef struct {
  char name[64];
  uint64_t count, min, max, sum;
} Region;

typedef struct {
  Region regions[kMaxRegions];
  int open_id;  // -1 when no region is open
  uint64_t open_cycle;
  int nested_errors;
  char line[kLineMax];
  size_t line_len;
  char* console;  // all non-@ lines, JSON-escaped, joined
  size_t console_len, console_cap;
  FILE* input;  // --input, or NULL
  uint64_t input_overrun;
} Harness;

static void append_console(Harness* h, const char* s) {
  size_t n = strlen(s);
  if (h->console_len + 2 * n + 8 > h->console_cap) {
    h->console_cap = (h->console_cap + 2 * n + 8) * 2;
    h->console = realloc(h->console, h->console_cap);
    if (!h->console) {
      fprintf(stderr, "avr_cycles: out of memory\n");
      exit(3);
    }
  }
  char* out = h->console + h->console_len;
  if (h->console_len) *out++ = ',';
  *out++ = '"';
  for (const char* p = s; *p; ++p) {
    if (*p == '"' || *p == '\\') *out++ = '\\';
    *out++ = (*p >= 0x20 && *p < 0x7f) ? *p : '?';
  }
  *out++ = '"';
  *out = 0;
  h->console_len = (size_t)(out - h->console);
}

static void finish_line(Harness* h) {
  h->line[h->line_len] = 0;
  int id = 0;
  char name[64];
  if (sscanf(h->line, "@region %d %63s", &id, name) == 2 && id > 0 && id < kMaxRegions) {
    snprintf(h->regions[id].name, sizeof h->regions[id].name, "%s", name);
  } else {
    append_console(h, h->line);
  }
  h->line_len = 0;
}

static void on_marker(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
  Harness* h = param;
  avr->data[addr] = v;
  if (v != 0) {
    if (h->open_id >= 0) h->nested_errors++;
    h->open_id = v;
    h->open_cycle = avr->cycle;
    return;
  }
  if (h->open_id < 0) {
    h->nested_errors++;
    return;
  }
  Region* r = &h->regions[h->open_id];
  uint64_t d = avr->cycle - h->open_cycle;
  if (r->count == 0 || d < r->min) r->min = d;
  if (d > r->max) r->max = d;
  r->sum += d;
  r->count++;
  h->open_id = -1;
}

static void on_console(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
  Harness* h = param;
  avr->data[addr] = v;
  if (v == '\n' || h->line_len + 1 >= kLineMax) {
    finish_line(h);
    if (v == '\n') return;
  }
  if (v != '\r') h->line[h->line_len++] = (char)v;
}

static uint8_t on_input(avr_t* avr, avr_io_addr_t addr, void* param) {
  Harness* h = param;
  int c = h->input ? fgetc(h->input) : EOF;
  if (c == EOF) {
    h->input_overrun++;
    c = 0;
  }
  avr->data[addr] = (uint8_t)c;
  return (uint8_t)c;
}

static void sleep_none(avr_t* avr, avr_cycle_count_t how_long) {
  (void)avr;
  (void)how_long;
}

// simavr logs through a global logger that prints to stdout; send it to stderr so stdout carries
// only the JSON report.
static void log_to_stderr(avr_t* avr, const int level, const char* format, va_list ap) {
  (void)avr;
  if (level <= LOG_WARNING) vfprintf(stderr, format, ap);
}

static void usage(void) {
  fprintf(stderr,
          "usage: avr_cycles [--mcu NAME] [--freq HZ] [--max-cycles N] [--input FILE] "
          "FIRMWARE.elf\n"
          "Runs the ELF in simavr and prints the cycles between GPIOR0 markers as JSON.\n");
}

int main(int argc, char** argv) {
  const char* mcu = NULL;
  uint32_t freq = 0;
  uint64_t max_cycles = 2000000000ULL;
  const char* path = NULL;
  const char* input = NULL;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--mcu") && i + 1 < argc) {
      mcu = argv[++i];
    } else if (!strcmp(argv[i], "--freq") && i + 1 < argc) {
      freq = (uint32_t)strtoul(argv[++i], NULL, 10);
    } else if (!strcmp(argv[i], "--max-cycles") && i + 1 < argc) {
      max_cycles = strtoull(argv[++i], NULL, 10);
    } else if (!strcmp(argv[i], "--input") && i + 1 < argc) {
      input = argv[++i];
    } else if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage();
      return 0;
    } else if (argv[i][0] != '-' && !path) {
      path = argv[i];
    } else {
      usage();
      return 2;
    }
  }
  if (!path) {
    usage();
    return 2;
  }

  avr_global_logger_set(log_to_stderr);
  elf_firmware_t fw;
  memset(&fw, 0, sizeof fw);
  if (elf_read_firmware(path, &fw) != 0) {
    fprintf(stderr, "avr_cycles: cannot read ELF %s\n", path);
    return 2;
  }
  if (mcu) snprintf(fw.mmcu, sizeof fw.mmcu, "%s", mcu);
  if (!fw.mmcu[0]) snprintf(fw.mmcu, sizeof fw.mmcu, "%s", "atmega2560");
  if (freq) fw.frequency = freq;
  if (!fw.frequency) fw.frequency = 16000000;

  avr_t* avr = avr_make_mcu_by_name(fw.mmcu);
  if (!avr) {
    fprintf(stderr, "avr_cycles: unknown MCU %s\n", fw.mmcu);
    return 2;
  }
  avr_init(avr);
  avr->log = LOG_NONE;  // keep stdout for the JSON report
  avr_load_firmware(avr, &fw);
  avr->sleep = sleep_none;  // simulated time only: never sleep in real time
  const uint32_t static_end = (uint32_t)avr->ioend + 1u + fw.datasize + fw.bsssize;
  for (uint32_t a = static_end; a <= avr->ramend; ++a) avr->data[a] = kPaint;

  static Harness h;
  h.open_id = -1;
  if (input) {
    h.input = fopen(input, "rb");
    if (!h.input) {
      fprintf(stderr, "avr_cycles: cannot open input %s\n", input);
      return 2;
    }
  }
  avr_register_io_read(avr, kInputAddr, on_input, &h);
  avr_register_io_write(avr, kMarkerAddr, on_marker, &h);
  avr_register_io_write(avr, kConsoleAddr, on_console, &h);

  int state = cpu_Running;
  while (state != cpu_Done && state != cpu_Crashed && avr->cycle < max_cycles) {
    state = avr_run(avr);
  }
  if (h.line_len) finish_line(&h);
  uint32_t lowest = avr->ramend + 1u;
  for (uint32_t a = static_end; a <= avr->ramend; ++a) {
    if (avr->data[a] != kPaint) {
      lowest = a;
      break;
    }
  }
  const uint32_t stack_peak = avr->ramend + 1u - lowest;

  const char* how = state == cpu_Done ? "done" : state == cpu_Crashed ? "crashed" : "timeout";
  uint64_t overhead = 0;
  for (int i = 1; i < kMaxRegions; ++i) {
    if (h.regions[i].count && !strcmp(h.regions[i].name, "empty")) overhead = h.regions[i].min;
  }
  printf("{\"elf\": \"%s\", \"mcu\": \"%s\", \"frequency_hz\": %" PRIu32
         ", \"state\": \"%s\", \"total_cycles\": %" PRIu64
         ", \"marker_errors\": %d,"
         " \"static_ram_bytes\": %" PRIu32 ", \"stack_peak_bytes\": %" PRIu32
         ", \"overhead_cycles\": %" PRIu64 ", \"input_overrun\": %" PRIu64 ", \"regions\": {",
         path, fw.mmcu, fw.frequency, how, (uint64_t)avr->cycle, h.nested_errors,
         fw.datasize + fw.bsssize, stack_peak, overhead, h.input_overrun);
  int first = 1;
  for (int i = 1; i < kMaxRegions; ++i) {
    Region* r = &h.regions[i];
    if (!r->count) continue;
    char fallback[16];
    snprintf(fallback, sizeof fallback, "region%d", i);
    printf("%s\n  \"%s\": {\"id\": %d, \"count\": %" PRIu64 ", \"min\": %" PRIu64
           ", \"max\": %" PRIu64 ", \"mean\": %.1f, \"net_max\": %" PRIu64 "}",
           first ? "" : ",", r->name[0] ? r->name : fallback, i, r->count, r->min, r->max,
           (double)r->sum / (double)r->count, r->max - overhead);
    first = 0;
  }
  printf("},\n \"console\": [%s]}\n", h.console ? h.console : "");
  free(h.console);
  if (h.input) fclose(h.input);
  return state == cpu_Done && h.nested_errors == 0 ? 0 : 1;
}
