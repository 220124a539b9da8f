// Saving and loading maps (issue 24): a versioned, checksummed binary format of our own
// (docs/map_format.md documents it byte by byte), so that a map built once can be loaded after
// a reboot and localized against.
//
// Why our own format rather than FlatBuffers, Cap'n Proto or cereal: the map is a handful of
// flat arrays (keyframe poses, keypoints, descriptors, observations, keyframe images) whose
// every size and index must be validated against each other before use anyway; a schema
// compiler would add a build step and a dependency for what is ~300 lines of explicit,
// little-endian reads with bounds checks. The checksum is zlib's CRC-32 (zlib1g-dev, already a
// dependency of OpenCV); keyframe images are stored as PNG (OpenCV, lossless).
//
// What is saved: the valid keyframes (pose, stamp, features with descriptors, image) and the
// valid points (position, descriptor, observations, first keyframe, viewing normal and
// distance range, counters) that keep at least two observations among the saved keyframes.
// Invalid points and keyframes (V(X) = 0, Sec. 4) are not saved. Covisibility is the
// observation lists (core/map.h computes it from them); the place-recognition vectors and the
// SIFT KD-tree are rebuilt on load from the descriptors (core/mapper.h Mapper::load).
//
// Loading checks, in this order, and throws MapFormatError with a message naming the problem:
// size, magic, format version, payload size (truncated), CRC-32 (corrupt), then every count,
// size and index while it decodes (nothing is used before it is checked). check_map_compatible()
// then refuses a map made with another camera model, intrinsics, image size or feature mode,
// naming both values.
//
// Writing is atomic: the bytes go to a temporary file beside the target, which is fsync'ed and
// renamed over it, then the directory is fsync'ed: a power cut leaves either the previous file
// or the new one, never a broken one. With keep > 1 the previous maps are kept as FILE.1 ..
// FILE.(keep-1) (hard links, so FILE itself is never missing).
//
// Saving while running (issue 24, core/mapper.h MapSaveWriter): the thread that owns the map
// takes copy_map_for_save() (a deep copy of exactly what encode_map writes) and another,
// low-priority thread encodes and writes that copy with save_map_file(); the file is the one
// encode_map would have made of the map at the time of the copy, byte for byte.
//
// Ownership: plain values in and out. Threads: any; encode_map and copy_map_for_save read a
// Map that the caller owns (the mapper thread, core/mapper.h), or a copy the caller owns.
// Plain file I/O only (no devices, no threads).
// Allocates: start-up, shutdown and save requests, never per frame.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/features.h"
#include "core/map.h"

namespace rdslam {

constexpr uint32_t kMapFormatVersion = 1;

class MapFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// What a map file holds (its header, and counts).
struct MapInfo {
  uint32_t version = 0;
  CameraModel camera;
  std::string feature_mode;  // orb | sift
  int descriptor_bytes = 0;
  int levels = 0;
  double scale_factor = 0.0;
  int keyframes = 0;
  int points = 0;
  int64_t observations = 0;
  int64_t features = 0;        // keypoints over all keyframes
  int images = 0;              // keyframes saved with their image
  int64_t image_bytes = 0;     // PNG bytes of those images
  int64_t saved_unix_s = 0;    // wall clock at save time
  int64_t first_stamp_ns = 0;  // oldest keyframe stamp
  int64_t last_stamp_ns = 0;   // newest keyframe stamp
  uint64_t file_bytes = 0;
};

// Serialises the valid part of `map` (see the header comment) with the camera and feature
// settings it was made with. `info` (optional) receives the counts written. The header's save
// time is `saved_unix_s`, or the wall clock now when it is negative.
std::vector<uint8_t> encode_map(const Map& map, const CameraModel& camera,
                                const FeatureParams& features, MapInfo* info = nullptr,
                                int64_t saved_unix_s = -1);

// The part of `map` that encode_map writes, deep-copied (keyframe features and images included:
// nothing is shared with `map`, which its owner may change right after): the valid keyframes,
// the saved points and the id counters. encode_map of the copy equals encode_map of `map`
// (same saved_unix_s). Costs memory copies only (no image encoding); tests/unit/test_map_io.cpp.
Map copy_map_for_save(const Map& map);

// Validates and decodes a whole map file's bytes. Throws MapFormatError.
Map decode_map(const std::vector<uint8_t>& bytes, MapInfo* info = nullptr);

// The header and counts only (the checksum is still verified). Throws MapFormatError.
MapInfo decode_map_info(const std::vector<uint8_t>& bytes);

// Empty when a map with `info` can be used with this camera and feature mode; otherwise a
// message naming the field and both values.
std::string check_map_compatible(const MapInfo& info, const CameraModel& camera,
                                 const FeatureParams& features);

// Reads a whole file. Throws MapFormatError naming the path when it cannot.
std::vector<uint8_t> read_map_file(const std::string& path);

// Atomic write (see the header comment); keeps `keep` - 1 previous versions as path.1, ...
// Throws MapFormatError naming the path and the system error; the previous file is untouched
// then and the temporary file removed.
void write_map_file_atomic(const std::string& path, const std::vector<uint8_t>& bytes,
                           int keep = 1);

// encode_map + write_map_file_atomic. False with *error set when either failed (the previous
// file is untouched then); `info` (optional) receives what was written, `*ms` the time taken.
bool save_map_file(const Map& map, const CameraModel& camera, const FeatureParams& features,
                   const std::string& path, int keep, std::string* error, MapInfo* info = nullptr,
                   double* ms = nullptr, int64_t saved_unix_s = -1);

}  // namespace rdslam
