// Loads an accelerations CSV (docs/design.md §4: t, then <link>.<i>.x/y/z per sensor, optional
// <link>.<i>.gx/gy/gz, optional truth columns, which are ignored) into one MotionTrack per sensor.
// Kept apart from the models: this is the only file that touches the file system.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sim/devices/motion.hpp"

namespace ja {
namespace sim {

using NamedTracks = std::vector<std::pair<std::string, std::unique_ptr<MotionTrack>>>;

/// Parses CSV text; on failure returns false and says which line and field.
bool ParseAccelCsv(const std::string& text, NamedTracks* out, std::string* error);
/// Reads and parses a file.
bool LoadAccelCsv(const char* path, NamedTracks* out, std::string* error);

}  // namespace sim
}  // namespace ja
