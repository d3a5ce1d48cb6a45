// Protocol tests against the shared vectors (protocol/vectors/, also checked by the Python tests):
//  - every golden vector: fields -> encode_message == golden frame, byte for byte;
//    golden frame -> byte-wise FrameDecoder -> decode -> the same fields -> the same bytes again;
//  - every damaged stream: the decoder accepts exactly the listed frames and reports the listed
//    counts (schema_errors excepted: checking a hello's schema hash is the host's job);
//  - hand-picked framing cases (CRC check value, bounded oversize, in-place COBS).
// Usage: test_protocol golden.txt streams.txt
#include <stdio.h>
#include <string.h>

#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "protocol/crc16.hpp"
#include "protocol/frame.hpp"
#include "protocol/messages.hpp"

namespace {

using ja::proto::DecodeEvent;
using ja::proto::FrameDecoder;

int g_failures = 0;

#define CHECK(cond, ...)                                                       \
  do {                                                                         \
    if (!(cond)) {                                                             \
      ++g_failures;                                                            \
      fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond); \
      fprintf(stderr, __VA_ARGS__);                                            \
      fprintf(stderr, "\n");                                                   \
    }                                                                          \
  } while (0)

std::vector<uint8_t> from_hex(const std::string& hex) {
  std::vector<uint8_t> out;
  for (size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  }
  return out;
}

struct FieldValue {
  bool is_int = true;
  long long value = 0;
  std::vector<uint8_t> bytes;
};

struct Vector {
  std::string name, message;
  uint16_t seq = 0;
  uint32_t t_us = 0;
  std::map<std::string, FieldValue> fields;
  std::vector<uint8_t> frame;
};

struct StreamVector {
  std::string name;
  std::vector<uint8_t> bytes;
  std::map<std::string, uint32_t> counts;
  std::vector<std::pair<int, int>> frames;
};

std::vector<Vector> load_golden(const char* path) {
  std::ifstream in(path);
  std::vector<Vector> out;
  Vector cur;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "vector") {
      cur = Vector();
      ls >> cur.name;
    } else if (key == "message") {
      ls >> cur.message;
    } else if (key == "seq") {
      unsigned long v;
      ls >> v;
      cur.seq = static_cast<uint16_t>(v);
    } else if (key == "t_us") {
      unsigned long v;
      ls >> v;
      cur.t_us = static_cast<uint32_t>(v);
    } else if (key == "field") {
      std::string name, kind, value;
      ls >> name >> kind >> value;
      FieldValue f;
      f.is_int = kind == "int";
      if (f.is_int) {
        f.value = std::stoll(value);
      } else {
        f.bytes = from_hex(value);
      }
      cur.fields[name] = f;
    } else if (key == "frame") {
      std::string hex;
      ls >> hex;
      cur.frame = from_hex(hex);
    } else if (key == "end") {
      out.push_back(cur);
    }
  }
  return out;
}

std::vector<StreamVector> load_streams(const char* path) {
  std::ifstream in(path);
  std::vector<StreamVector> out;
  StreamVector cur;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "stream") {
      cur = StreamVector();
      ls >> cur.name;
    } else if (key == "bytes") {
      std::string hex;
      ls >> hex;
      cur.bytes = from_hex(hex);
    } else if (key == "count") {
      std::string name;
      unsigned long v;
      ls >> name >> v;
      cur.counts[name] = static_cast<uint32_t>(v);
    } else if (key == "frame") {
      int id, seq;
      ls >> id >> seq;
      cur.frames.emplace_back(id, seq);
    } else if (key == "end") {
      out.push_back(cur);
    }
  }
  return out;
}

std::string key_of(const char* group, int index, const char* name) {
  if (group == nullptr) return name;
  return std::string(group) + "." + std::to_string(index) + "." + name;
}

// Fills a message from the vector's fields (visit() calls back for every field).
struct Setter {
  const Vector& v;
  int assigned = 0;

  void group(const char* name, uint8_t& count, uint8_t max) {
    int n = 0;
    const std::string prefix = std::string(name) + ".";
    for (const auto& kv : v.fields) {
      if (kv.first.compare(0, prefix.size(), prefix) == 0) {
        n = std::max(n, std::stoi(kv.first.substr(prefix.size())) + 1);
      }
    }
    CHECK(n <= max, "%s: %d items > %d", v.name.c_str(), n, max);
    count = static_cast<uint8_t>(n);
  }
  template <class T>
  void operator()(const char* group, int index, const char* name, T& ref) {
    const std::string key = key_of(group, index, name);
    auto it = v.fields.find(key);
    CHECK(it != v.fields.end(), "%s: no value for %s", v.name.c_str(), key.c_str());
    if (it == v.fields.end()) return;
    ++assigned;
    assign(it->second, ref);
  }
  template <class T>
  static void assign(const FieldValue& f, T& ref) {
    ref = static_cast<T>(f.value);
  }
  template <size_t N>
  static void assign(const FieldValue& f, char (&ref)[N]) {
    memset(ref, 0, N);
    memcpy(ref, f.bytes.data(), std::min(N, f.bytes.size()));
  }
  template <size_t N>
  static void assign(const FieldValue& f, ja::proto::Text<N>& ref) {
    ref.len = static_cast<uint8_t>(std::min(N, f.bytes.size()));
    memcpy(ref.data, f.bytes.data(), ref.len);
  }
};

// Compares a decoded message with the vector's fields.
struct Checker {
  const Vector& v;
  int seen = 0;

  void group(const char*, uint8_t&, uint8_t) {}
  template <class T>
  void operator()(const char* group, int index, const char* name, T& ref) {
    const std::string key = key_of(group, index, name);
    auto it = v.fields.find(key);
    CHECK(it != v.fields.end(), "%s: decoded unexpected field %s", v.name.c_str(), key.c_str());
    if (it == v.fields.end()) return;
    ++seen;
    CHECK(same(it->second, ref), "%s: field %s differs", v.name.c_str(), key.c_str());
  }
  template <class T>
  static bool same(const FieldValue& f, const T& ref) {
    return f.is_int && static_cast<long long>(ref) == f.value;
  }
  template <size_t N>
  static bool same(const FieldValue& f, const char (&ref)[N]) {
    return f.bytes.size() == N && memcmp(ref, f.bytes.data(), N) == 0;
  }
  template <size_t N>
  static bool same(const FieldValue& f, const ja::proto::Text<N>& ref) {
    return f.bytes.size() == ref.len && memcmp(ref.data, f.bytes.data(), ref.len) == 0;
  }
};

template <class Msg>
void check_vector(const Vector& v) {
  // Encode from the fields.
  Msg msg;
  memset(&msg, 0, sizeof msg);
  Setter setter{v};
  msg.visit(setter);
  CHECK(setter.assigned == static_cast<int>(v.fields.size()), "%s: %d of %zu fields set",
        v.name.c_str(), setter.assigned, v.fields.size());
  uint8_t buf[ja::proto::kMaxFrameBytes];
  const size_t n = ja::proto::encode_message(msg, v.seq, v.t_us, buf, sizeof buf);
  CHECK(n == v.frame.size() && memcmp(buf, v.frame.data(), n) == 0,
        "%s: encoded frame differs from golden (%zu vs %zu bytes)", v.name.c_str(), n,
        v.frame.size());

  // Decode the golden frame byte by byte.
  FrameDecoder dec;
  int frames = 0;
  for (size_t i = 0; i < v.frame.size(); ++i) {
    const DecodeEvent ev = dec.push(v.frame[i]);
    if (ev == DecodeEvent::kFrame) {
      ++frames;
      CHECK(i + 1 == v.frame.size(), "%s: frame ends early", v.name.c_str());
    }
  }
  CHECK(frames == 1, "%s: %d frames decoded", v.name.c_str(), frames);
  CHECK(dec.header().msg_id == Msg::kId && dec.header().seq == v.seq && dec.header().t_us == v.t_us,
        "%s: header differs", v.name.c_str());
  Msg back;
  memset(&back, 0, sizeof back);
  CHECK(back.decode(dec.payload(), dec.payload_size()), "%s: payload does not decode",
        v.name.c_str());
  Checker checker{v};
  back.visit(checker);
  CHECK(checker.seen == static_cast<int>(v.fields.size()), "%s: decoded %d of %zu fields",
        v.name.c_str(), checker.seen, v.fields.size());
  uint8_t again[ja::proto::kMaxFrameBytes];
  const size_t m = ja::proto::encode_message(back, v.seq, v.t_us, again, sizeof again);
  CHECK(m == n && memcmp(again, buf, n) == 0, "%s: re-encoding differs", v.name.c_str());
  // A payload one byte longer is refused.
  // (Only log, whose text fills the rest of the payload, may take one byte more.)
  CHECK(!back.decode(dec.payload(), dec.payload_size() + 1) || v.message == "log",
        "%s: accepts a longer payload", v.name.c_str());
}

void check_golden(const std::vector<Vector>& vectors) {
  std::map<std::string, int> per_message;
  for (const Vector& v : vectors) {
    bool known = false;
#define JA_CHECK_ONE(Type, id, name)  \
  if (v.message == name) {            \
    check_vector<ja::proto::Type>(v); \
    known = true;                     \
  }
    JA_PROTO_FOR_EACH_MESSAGE(JA_CHECK_ONE)
#undef JA_CHECK_ONE
    CHECK(known, "unknown message %s", v.message.c_str());
    ++per_message[v.message];
  }
  int messages = 0;
#define JA_COUNT_ONE(Type, id, name) \
  ++messages;                        \
  CHECK(per_message[name] >= 1, "no golden vector for %s", name);
  JA_PROTO_FOR_EACH_MESSAGE(JA_COUNT_ONE)
#undef JA_COUNT_ONE
  printf("golden vectors: %zu vectors, %d messages\n", vectors.size(), messages);
}

void check_streams(const std::vector<StreamVector>& streams) {
  for (const StreamVector& s : streams) {
    FrameDecoder dec;
    std::vector<std::pair<int, int>> frames;
    for (uint8_t b : s.bytes) {
      if (dec.push(b) == DecodeEvent::kFrame) {
        frames.emplace_back(dec.header().msg_id, dec.header().seq);
      }
    }
    const ja::proto::DecoderStats& st = dec.stats();
    const std::map<std::string, uint32_t> got = {
        {"frames", st.frames},
        {"crc_errors", st.crc_errors},
        {"malformed", st.malformed},
        {"oversize", st.oversize},
        {"version_errors", st.version_errors},
        {"frames_lost", st.frames_lost},
        {"bytes_skipped", st.bytes_skipped},
    };
    for (const auto& kv : got) {
      auto it = s.counts.find(kv.first);
      CHECK(it != s.counts.end() && it->second == kv.second, "stream %s: %s = %u, expected %u",
            s.name.c_str(), kv.first.c_str(), kv.second, it == s.counts.end() ? 0u : it->second);
    }
    CHECK(frames == s.frames, "stream %s: accepted frames differ", s.name.c_str());
  }
  printf("damaged streams: %zu\n", streams.size());
}

void check_framing_basics() {
  const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  CHECK(ja::proto::crc16(check, sizeof check) == 0x29B1, "CRC-16/CCITT-FALSE check value");
  CHECK(ja::proto::kMaxEncoded == 251 && ja::proto::kMaxFrameBytes == 252, "limits");

  // A payload of 240 zero bytes: every byte becomes a COBS code, still exactly one byte longer.
  uint8_t payload[ja::proto::kMaxPayload] = {};
  uint8_t buf[ja::proto::kMaxFrameBytes];
  const ja::proto::FrameHeader h = {ja::proto::kProtocolVersion, 0x02, 0, 0};
  const size_t n = ja::proto::encode_frame(h, payload, sizeof payload, buf, sizeof buf);
  CHECK(n == ja::proto::kMaxFrameBytes, "max frame is %zu bytes", n);
  for (size_t i = 0; i + 1 < n; ++i) CHECK(buf[i] != 0, "zero inside the frame at %zu", i);
  CHECK(ja::proto::encode_frame(h, payload, sizeof payload, buf, sizeof buf - 1) == 0,
        "too small a buffer is refused");
  CHECK(ja::proto::encode_frame(h, payload, ja::proto::kMaxPayload + 1, buf, 1000) == 0,
        "too long a payload is refused");

  // A long run without a delimiter is counted once as oversize and the next frame still arrives.
  FrameDecoder dec;
  for (int i = 0; i < 100000; ++i) dec.push(static_cast<uint8_t>(1 + i % 255));
  CHECK(dec.push(0) == DecodeEvent::kOversize, "oversize reported");
  DecodeEvent last = DecodeEvent::kNone;
  for (size_t i = 0; i < n; ++i) last = dec.push(buf[i]);
  CHECK(last == DecodeEvent::kFrame && dec.payload_size() == ja::proto::kMaxPayload,
        "frame after oversize");
  CHECK(dec.stats().oversize == 1 && dec.stats().bytes_skipped == 100000, "oversize counts");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s golden.txt streams.txt\n", argv[0]);
    return 2;
  }
  const std::vector<Vector> golden = load_golden(argv[1]);
  const std::vector<StreamVector> streams = load_streams(argv[2]);
  CHECK(golden.size() >= 2, "no golden vectors read from %s", argv[1]);
  CHECK(streams.size() >= 5, "no streams read from %s", argv[2]);
  check_framing_basics();
  check_golden(golden);
  check_streams(streams);
  if (g_failures) {
    fprintf(stderr, "%d check(s) failed\n", g_failures);
    return 1;
  }
  printf("all protocol checks passed\n");
  return 0;
}
