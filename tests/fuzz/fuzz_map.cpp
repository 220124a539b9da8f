// libFuzzer target: map files as `rdslam run/replay --map` and `rdslam map info` read them
// (core/map_io.h: decode_map_info, decode_map, check_map_compatible). Input: one byte of
// flags, then the file. The format is checksummed, so a mutated file almost always stops at the
// CRC check; flag bit 0 makes this target first write the payload's true CRC-32 into the
// preamble (and bit 1 the payload's true size), so that mutations reach the decoding of the
// header, keyframes, images and points behind it. A malformed map must end in MapFormatError;
// anything else (a crash, a sanitizer report, another exception) is a bug.
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/map_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t flags = data[0];
  std::vector<uint8_t> bytes(data + 1, data + size);
  constexpr size_t kPreamble = 24;  // magic 8, version 4, payload size 8, CRC-32 4
  if (bytes.size() >= kPreamble) {
    const size_t payload = bytes.size() - kPreamble;
    if (flags & 2) {
      const uint64_t n = payload;
      std::memcpy(bytes.data() + 12, &n, 8);
    }
    if (flags & 1) {
      const uint32_t crc =
          static_cast<uint32_t>(crc32(0L, bytes.data() + kPreamble, static_cast<uInt>(payload)));
      std::memcpy(bytes.data() + 20, &crc, 4);
    }
  }
  try {
    const rdslam::MapInfo info = rdslam::decode_map_info(bytes);
    (void)rdslam::check_map_compatible(info, rdslam::CameraModel{}, rdslam::FeatureParams{});
    rdslam::MapInfo full;
    const rdslam::Map map = rdslam::decode_map(bytes, &full);
    (void)map.count_valid_points();
  } catch (const rdslam::MapFormatError&) {
  }
  return 0;
}
