#pragma once
// SHA-256 (FIPS 180-4) of a byte string, as 64 lowercase hex digits. Used to record exactly which
// scene produced a result (summary.json `scene_sha256`, checkpoints).
#include <string>
#include <string_view>

namespace grainwave {
std::string sha256_hex(std::string_view data);
}
