// No allocation in the application: operator new aborts from the first line of main, then the
// app starts, takes commands, streams, and rides through faults. Built without sanitizers.
#include <stdio.h>
#include <stdlib.h>

#include <new>

#include "app_fakes.hpp"

namespace {
bool g_forbid = false;
}

void* operator new(size_t n) {
  if (g_forbid) {
    fputs("test_app_no_alloc: operator new called\n", stderr);
    abort();
  }
  void* p = malloc(n ? n : 1);
  if (!p) abort();
  return p;
}
void* operator new[](size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { free(p); }
void operator delete[](void* p) noexcept { free(p); }
void operator delete(void* p, size_t) noexcept { free(p); }
void operator delete[](void* p, size_t) noexcept { free(p); }

namespace {
ja_test::Board board;  // static storage: ~1 MB of frame log
}

int main() {
  namespace proto = ja::proto;
  g_forbid = true;
  board.AddDefaultChips();
  static ja::app::App app(board.hal);
  app.Begin();
  proto::StartStream s = {};
  s.every = 1;
  s.mode = proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus |
           proto::stream_mode::kEstimate | proto::stream_mode::kSamples;
  s.status_interval_ms = 100;
  board.Command(s);
  board.Command(proto::GetInfo());
  board.Run(app, 200000);
  board.bus.chips[1].nack = true;
  board.bus.chips[2].frozen = true;
  board.Run(app, 300000);
  board.bus.chips[1].nack = false;
  board.bus.chips[2].frozen = false;
  board.Run(app, 600000);
  board.Command(proto::StopStream());
  proto::SaveEeprom save;
  save.confirm = ja::app::kSaveConfirm;
  board.Command(save);
  board.Run(app, 10000);
  const int frames = board.frame_count;
  printf("test_app_no_alloc: %d frames, %u loops, no allocation\n", frames,
         static_cast<unsigned>(app.loops()));
  return frames > 500 ? 0 : 1;
}
