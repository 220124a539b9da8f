#include "core/map_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <opencv2/imgcodecs.hpp>
#include <unordered_set>

namespace rdslam {

namespace {

constexpr char kMagic[8] = {'R', 'D', 'S', 'L', 'A', 'M', 'A', 'P'};
// magic (8) + version (4) + payload bytes (8) + payload CRC-32 (4).
constexpr size_t kPreamble = 24;
// Sanity bounds of the decoder (a map far beyond the caps is refused, not allocated).
constexpr int64_t kMaxKeyframes = 1000000;
constexpr int64_t kMaxPoints = 100000000;
constexpr int64_t kMaxFeatures = 100000;
constexpr int64_t kMaxObservations = 100000;
constexpr int kMaxImageSide = 8192;

class Writer {
 public:
  template <class T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable<T>::value, "pod");
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    buf.insert(buf.end(), p, p + sizeof(T));
  }
  void bytes(const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    buf.insert(buf.end(), b, b + n);
  }
  void str(const std::string& s) {
    pod(static_cast<uint32_t>(s.size()));
    bytes(s.data(), s.size());
  }
  void pose(const Pose& T) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) pod(T.R(r, c));
    }
    for (int k = 0; k < 3; ++k) pod(T.t(k));
  }
  void vec3(const Eigen::Vector3d& v) {
    for (int k = 0; k < 3; ++k) pod(v(k));
  }
  std::vector<uint8_t> buf;
};

class Reader {
 public:
  Reader(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  template <class T>
  T pod(const char* what) {
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, p_ + off_, sizeof(T));
    off_ += sizeof(T);
    return v;
  }
  const uint8_t* bytes(size_t n, const char* what) {
    need(n, what);
    const uint8_t* b = p_ + off_;
    off_ += n;
    return b;
  }
  std::string str(const char* what, size_t max_len = 256) {
    const uint32_t n = pod<uint32_t>(what);
    if (n > max_len) fail(std::string(what) + ": length " + std::to_string(n) + " too large");
    const uint8_t* b = bytes(n, what);
    return std::string(reinterpret_cast<const char*>(b), n);
  }
  // An integer field that must lie in [lo, hi].
  int64_t count(const char* what, int64_t lo, int64_t hi) {
    const int64_t v = pod<int64_t>(what);
    if (v < lo || v > hi) {
      fail(std::string(what) + ": " + std::to_string(v) + " outside [" + std::to_string(lo) + ", " +
           std::to_string(hi) + "]");
    }
    return v;
  }
  double finite(const char* what) {
    const double v = pod<double>(what);
    if (!std::isfinite(v)) fail(std::string(what) + ": not a finite number");
    return v;
  }
  Pose pose(const char* what) {
    Pose T;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T.R(r, c) = finite(what);
    }
    for (int k = 0; k < 3; ++k) T.t(k) = finite(what);
    const double orth = (T.R * T.R.transpose() - Eigen::Matrix3d::Identity()).norm();
    if (orth > 1e-6 || T.R.determinant() < 0) fail(std::string(what) + ": not a rotation");
    return T;
  }
  Eigen::Vector3d vec3(const char* what) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v(k) = finite(what);
    return v;
  }
  size_t offset() const { return off_; }
  size_t left() const { return n_ - off_; }
  [[noreturn]] void fail(const std::string& m) const {
    throw MapFormatError("map: invalid " + m + " (at payload byte " + std::to_string(off_) + ")");
  }

 private:
  void need(size_t n, const char* what) const {
    if (n > n_ - off_) {
      throw MapFormatError("map: payload ends inside " + std::string(what) + " (at byte " +
                           std::to_string(off_) + " of " + std::to_string(n_) + ")");
    }
  }
  const uint8_t* p_;
  size_t n_;
  size_t off_ = 0;
};

void write_camera(Writer& w, const CameraModel& c) {
  w.str(c.model);
  w.pod(static_cast<int32_t>(c.width));
  w.pod(static_cast<int32_t>(c.height));
  for (double v : {c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2, c.k3, c.k4}) w.pod(v);
}

CameraModel read_camera(Reader& r) {
  CameraModel c;
  c.model = r.str("camera model");
  c.width = r.pod<int32_t>("camera width");
  c.height = r.pod<int32_t>("camera height");
  if (c.width < 1 || c.height < 1 || c.width > kMaxImageSide || c.height > kMaxImageSide) {
    r.fail("camera size " + std::to_string(c.width) + "x" + std::to_string(c.height));
  }
  for (double* v : {&c.fx, &c.fy, &c.cx, &c.cy, &c.k1, &c.k2, &c.p1, &c.p2, &c.k3, &c.k4}) {
    *v = r.finite("camera parameter");
  }
  return c;
}

uint32_t crc_of(const uint8_t* p, size_t n) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib takes uInt lengths: feed it in chunks.
  while (n > 0) {
    const uInt chunk = static_cast<uInt>(std::min<size_t>(n, 1u << 30));
    crc = crc32(crc, p, chunk);
    p += chunk;
    n -= chunk;
  }
  return static_cast<uint32_t>(crc);
}

// The saved subset of the map: valid keyframes; valid points with >= 2 observations among them.
struct Selection {
  std::vector<const Keyframe*> kfs;
  std::vector<const MapPoint*> points;
  std::unordered_set<int> kf_ids;
};

Selection select(const Map& map) {
  Selection s;
  for (const auto& [id, k] : map.keyframes) {
    if (!k.valid) continue;
    s.kfs.push_back(&k);
    s.kf_ids.insert(id);
  }
  for (const auto& [pid, p] : map.points) {
    if (!p.valid) continue;
    int n = 0;
    for (const auto& o : p.obs) n += s.kf_ids.count(o.kf) > 0;
    if (n >= 2) s.points.push_back(&p);
  }
  // Deterministic order (unordered_map iteration is not).
  std::sort(s.points.begin(), s.points.end(),
            [](const MapPoint* a, const MapPoint* b) { return a->id < b->id; });
  return s;
}

void write_features(Writer& w, const Features& f, int desc_bytes) {
  w.pod(static_cast<int32_t>(f.count));
  w.pod(static_cast<int32_t>(f.width));
  w.pod(static_cast<int32_t>(f.height));
  w.pod(f.cell_px);
  for (int i = 0; i < f.count; ++i) {
    const cv::KeyPoint& k = f.kps[size_t(i)];
    for (float v : {k.pt.x, k.pt.y, k.size, k.angle, k.response, f.un[size_t(i)].x,
                    f.un[size_t(i)].y, f.scale[size_t(i)]}) {
      w.pod(v);
    }
    w.pod(static_cast<int32_t>(k.octave));
    w.pod(static_cast<int32_t>(f.level[size_t(i)]));
  }
  for (int i = 0; i < f.count; ++i) w.bytes(f.desc_ptr(i), static_cast<size_t>(desc_bytes));
}

// `grid_extent` is cam.ideal_extent(), computed once per map by the caller.
void read_features(Reader& r, Features& f, bool binary, int desc_bytes, const CameraModel& cam,
                   const cv::Rect2d& grid_extent) {
  const int32_t count = r.pod<int32_t>("keyframe feature count");
  if (count < 0 || count > kMaxFeatures) r.fail("keyframe feature count " + std::to_string(count));
  f.count = count;
  f.width = r.pod<int32_t>("keyframe width");
  f.height = r.pod<int32_t>("keyframe height");
  if (f.width != cam.width || f.height != cam.height) {
    r.fail("keyframe size " + std::to_string(f.width) + "x" + std::to_string(f.height) +
           " (the camera's is " + std::to_string(cam.width) + "x" + std::to_string(cam.height) +
           ")");
  }
  f.cell_px = r.pod<float>("keyframe grid cell");
  if (!(f.cell_px >= 1.f && f.cell_px <= 4096.f)) r.fail("keyframe grid cell");
  f.set_grid_extent(grid_extent);  // the grid covers what the lens shows (not stored)
  f.binary = binary;
  const size_t n = static_cast<size_t>(count);
  f.kps.resize(n);
  f.un.resize(n);
  f.scale.resize(n);
  f.level.resize(n);
  f.cell_items.resize(n);
  for (size_t i = 0; i < n; ++i) {
    float v[8];
    for (float& x : v) {
      x = r.pod<float>("keypoint");
      if (!std::isfinite(x)) r.fail("keypoint: not a finite number");
    }
    cv::KeyPoint& k = f.kps[i];
    k.pt = cv::Point2f(v[0], v[1]);
    k.size = v[2];
    k.angle = v[3];
    k.response = v[4];
    f.un[i] = cv::Point2f(v[5], v[6]);
    f.scale[i] = v[7];
    k.octave = r.pod<int32_t>("keypoint octave");
    f.level[i] = r.pod<int32_t>("keypoint level");
    if (f.level[i] < 0 || f.level[i] > 64 || !(v[7] > 0.f)) r.fail("keypoint level/scale");
  }
  const int cols = binary ? desc_bytes : desc_bytes / 4;
  f.desc.create(std::max(1, count), cols, binary ? CV_8U : CV_32F);
  const uint8_t* d = r.bytes(n * static_cast<size_t>(desc_bytes), "descriptors");
  if (count > 0) std::memcpy(f.desc.data, d, n * static_cast<size_t>(desc_bytes));
  f.build_grid();
}

void fail_io(const std::string& what, const std::string& path, int err) {
  throw MapFormatError(what + " " + path + ": " + std::strerror(err));
}

std::string dir_of(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

}  // namespace

std::vector<uint8_t> encode_map(const Map& map, const CameraModel& camera,
                                const FeatureParams& features, MapInfo* info,
                                int64_t saved_unix_s) {
  const Selection s = select(map);
  const int desc_bytes = features.descriptor_bytes();
  Writer w;
  w.buf.reserve(1 << 20);
  // Header section.
  write_camera(w, camera);
  w.str(features.mode);
  w.pod(static_cast<int32_t>(desc_bytes));
  w.pod(static_cast<int32_t>(features.levels));
  w.pod(features.scale_factor);
  const int64_t saved = saved_unix_s >= 0 ? saved_unix_s : static_cast<int64_t>(std::time(nullptr));
  w.pod(saved);
  w.pod(static_cast<int64_t>(s.kfs.size()));
  w.pod(static_cast<int64_t>(s.points.size()));
  w.pod(static_cast<int64_t>(map.next_point_id));
  w.pod(static_cast<int64_t>(map.next_kf_id));
  w.pod(static_cast<int64_t>(map.kf_seq));
  MapInfo mi;
  mi.version = kMapFormatVersion;
  mi.camera = camera;
  mi.feature_mode = features.mode;
  mi.descriptor_bytes = desc_bytes;
  mi.levels = features.levels;
  mi.scale_factor = features.scale_factor;
  mi.saved_unix_s = saved;
  mi.keyframes = static_cast<int>(s.kfs.size());
  mi.points = static_cast<int>(s.points.size());
  // Keyframes.
  std::vector<uint8_t> png;
  const std::vector<int> png_params{cv::IMWRITE_PNG_COMPRESSION, 1};
  for (const Keyframe* k : s.kfs) {
    w.pod(static_cast<int64_t>(k->id));
    w.pod(k->stamp_ns);
    w.pose(k->T_cam_world);
    w.pod(static_cast<uint8_t>(k->fixed ? 1 : 0));
    write_features(w, k->features, desc_bytes);
    png.clear();
    if (!k->image.empty()) cv::imencode(".png", k->image, png, png_params);
    w.pod(static_cast<int64_t>(png.size()));
    w.bytes(png.data(), png.size());
    mi.features += k->features.count;
    mi.images += png.empty() ? 0 : 1;
    mi.image_bytes += static_cast<int64_t>(png.size());
    if (mi.first_stamp_ns == 0 || k->stamp_ns < mi.first_stamp_ns) mi.first_stamp_ns = k->stamp_ns;
    mi.last_stamp_ns = std::max(mi.last_stamp_ns, k->stamp_ns);
  }
  // Points.
  for (const MapPoint* p : s.points) {
    w.pod(p->id);
    w.vec3(p->p_world);
    if (p->desc.size() != static_cast<size_t>(desc_bytes)) {
      throw MapFormatError("map: point " + std::to_string(p->id) + " has a descriptor of " +
                           std::to_string(p->desc.size()) + " bytes, expected " +
                           std::to_string(desc_bytes));
    }
    w.bytes(p->desc.data(), p->desc.size());
    int64_t n = 0;
    for (const auto& o : p->obs) n += s.kf_ids.count(o.kf) > 0;
    w.pod(n);
    for (const auto& o : p->obs) {
      if (!s.kf_ids.count(o.kf)) continue;
      w.pod(static_cast<int64_t>(o.kf));
      w.pod(static_cast<int64_t>(o.feat));
    }
    mi.observations += n;
    const bool first_saved = s.kf_ids.count(p->first_kf) > 0;
    w.pod(static_cast<int64_t>(first_saved ? p->first_kf : -1));
    w.pod(static_cast<int64_t>(p->created_kf_seq));
    w.vec3(p->normal);
    w.pod(p->min_dist);
    w.pod(p->max_dist);
    w.pod(static_cast<int32_t>(p->missed));
    w.pod(static_cast<int32_t>(p->moved));
    w.pod(static_cast<int32_t>(p->unmatched));
  }
  std::vector<uint8_t> out(kPreamble + w.buf.size());
  const uint32_t version = kMapFormatVersion;
  const uint64_t payload = w.buf.size();
  const uint32_t crc = crc_of(w.buf.data(), w.buf.size());
  std::memcpy(out.data(), kMagic, 8);
  std::memcpy(out.data() + 8, &version, 4);
  std::memcpy(out.data() + 12, &payload, 8);
  std::memcpy(out.data() + 20, &crc, 4);
  if (payload > 0) std::memcpy(out.data() + kPreamble, w.buf.data(), payload);
  mi.file_bytes = out.size();
  if (info) *info = mi;
  return out;
}

Map copy_map_for_save(const Map& map) {
  const Selection s = select(map);
  Map out;
  out.next_point_id = map.next_point_id;
  out.next_kf_id = map.next_kf_id;
  out.kf_seq = map.kf_seq;
  for (const Keyframe* k : s.kfs) {
    Keyframe& c = out.keyframes[k->id];
    c.id = k->id;
    c.stamp_ns = k->stamp_ns;
    c.T_cam_world = k->T_cam_world;
    c.features.copy_from(k->features);  // deep: the owner's buffers are reused in place
    c.point_of = k->point_of;
    c.valid = k->valid;
    c.image = k->image.clone();  // deep, for the same reason
    c.fixed = k->fixed;
  }
  out.points.reserve(s.points.size());
  for (const MapPoint* p : s.points) out.points.emplace(p->id, *p);
  return out;
}

bool save_map_file(const Map& map, const CameraModel& camera, const FeatureParams& features,
                   const std::string& path, int keep, std::string* error, MapInfo* info, double* ms,
                   int64_t saved_unix_s) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const std::vector<uint8_t> bytes = encode_map(map, camera, features, info, saved_unix_s);
    write_map_file_atomic(path, bytes, keep);
  } catch (const std::exception& e) {
    if (error) *error = e.what();
    return false;
  }
  if (ms) {
    *ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  return true;
}

namespace {

// Checks the preamble and returns a reader over the verified payload.
Reader open_payload(const std::vector<uint8_t>& bytes) {
  if (bytes.size() < kPreamble) {
    throw MapFormatError("map: truncated: " + std::to_string(bytes.size()) +
                         " bytes, shorter than the " + std::to_string(kPreamble) +
                         "-byte preamble");
  }
  if (std::memcmp(bytes.data(), kMagic, 8) != 0) {
    throw MapFormatError("map: not an rdslam map file (bad magic)");
  }
  uint32_t version;
  uint64_t payload;
  uint32_t crc;
  std::memcpy(&version, bytes.data() + 8, 4);
  std::memcpy(&payload, bytes.data() + 12, 8);
  std::memcpy(&crc, bytes.data() + 20, 4);
  if (version != kMapFormatVersion) {
    throw MapFormatError("map: format version " + std::to_string(version) +
                         ", this rdslam reads version " + std::to_string(kMapFormatVersion));
  }
  const uint64_t have = bytes.size() - kPreamble;
  if (payload != have) {
    throw MapFormatError(std::string("map: ") + (have < payload ? "truncated" : "trailing bytes") +
                         ": payload is " + std::to_string(have) + " bytes, the header says " +
                         std::to_string(payload));
  }
  const uint32_t actual = crc_of(bytes.data() + kPreamble, have);
  if (actual != crc) {
    char m[128];
    std::snprintf(m, sizeof(m),
                  "map: checksum mismatch (CRC-32 %08x, the header says %08x): corrupt", actual,
                  crc);
    throw MapFormatError(m);
  }
  return Reader(bytes.data() + kPreamble, have);
}

struct Header {
  MapInfo info;
  int64_t n_kf = 0, n_pt = 0, next_point_id = 0, next_kf_id = 0, kf_seq = 0;
};

Header read_header(Reader& r) {
  Header h;
  MapInfo& mi = h.info;
  mi.version = kMapFormatVersion;
  mi.camera = read_camera(r);
  mi.feature_mode = r.str("feature mode");
  if (mi.feature_mode != "orb" && mi.feature_mode != "sift")
    r.fail("feature mode " + mi.feature_mode);
  mi.descriptor_bytes = r.pod<int32_t>("descriptor size");
  const int expect = mi.feature_mode == "sift" ? 512 : 32;
  if (mi.descriptor_bytes != expect) {
    r.fail("descriptor size " + std::to_string(mi.descriptor_bytes) + " for " + mi.feature_mode);
  }
  mi.levels = r.pod<int32_t>("pyramid levels");
  mi.scale_factor = r.finite("scale factor");
  mi.saved_unix_s = r.pod<int64_t>("save time");
  h.n_kf = r.count("keyframe count", 0, kMaxKeyframes);
  h.n_pt = r.count("point count", 0, kMaxPoints);
  h.next_point_id = r.count("next point id", 0, INT64_MAX / 2);
  h.next_kf_id = r.count("next keyframe id", 0, INT32_MAX / 2);
  h.kf_seq = r.count("keyframe counter", 0, INT32_MAX / 2);
  mi.keyframes = static_cast<int>(h.n_kf);
  mi.points = static_cast<int>(h.n_pt);
  return h;
}

// Decodes the body; with `map` null only counts (map info).
void read_body(Reader& r, Header& h, Map* map) {
  MapInfo& mi = h.info;
  const bool binary = mi.feature_mode == "orb";
  Features scratch;
  const cv::Rect2d grid_extent = mi.camera.ideal_extent();
  for (int64_t i = 0; i < h.n_kf; ++i) {
    const int64_t id = r.count("keyframe id", 0, h.next_kf_id - 1);
    Keyframe tmp;
    Keyframe* k = &tmp;
    if (map) {
      if (map->keyframes.count(static_cast<int>(id)))
        r.fail("keyframe id " + std::to_string(id) + " (twice)");
      k = &map->keyframes[static_cast<int>(id)];
    }
    k->id = static_cast<int>(id);
    k->stamp_ns = r.pod<int64_t>("keyframe stamp");
    k->T_cam_world = r.pose("keyframe pose");
    k->fixed = r.pod<uint8_t>("keyframe flag") != 0;
    read_features(r, map ? k->features : scratch, binary, mi.descriptor_bytes, mi.camera,
                  grid_extent);
    const Features& f = map ? k->features : scratch;
    k->point_of.assign(static_cast<size_t>(f.count), -1);
    const int64_t png = r.count("image size", 0, int64_t(1) << 31);
    const uint8_t* pb = r.bytes(static_cast<size_t>(png), "keyframe image");
    if (png > 0) {
      ++mi.images;
      mi.image_bytes += png;
      if (map) {
        const cv::Mat buf(1, static_cast<int>(png), CV_8U, const_cast<uint8_t*>(pb));
        k->image = cv::imdecode(buf, cv::IMREAD_UNCHANGED);
        if (k->image.empty() || k->image.cols != mi.camera.width ||
            k->image.rows != mi.camera.height || k->image.depth() != CV_8U ||
            (k->image.channels() != 1 && k->image.channels() != 3)) {
          r.fail("keyframe " + std::to_string(id) + " image (not a " +
                 std::to_string(mi.camera.width) + "x" + std::to_string(mi.camera.height) +
                 " 8-bit grey or BGR PNG)");
        }
      }
    }
    mi.features += f.count;
    if (mi.first_stamp_ns == 0 || k->stamp_ns < mi.first_stamp_ns) mi.first_stamp_ns = k->stamp_ns;
    mi.last_stamp_ns = std::max(mi.last_stamp_ns, k->stamp_ns);
  }
  for (int64_t i = 0; i < h.n_pt; ++i) {
    const int64_t pid = r.count("point id", 0, h.next_point_id - 1);
    MapPoint p;
    p.id = pid;
    p.p_world = r.vec3("point position");
    const uint8_t* d = r.bytes(static_cast<size_t>(mi.descriptor_bytes), "point descriptor");
    const int64_t n_obs = r.count("observation count", 2, kMaxObservations);
    mi.observations += n_obs;
    if (map) {
      if (map->points.count(pid)) r.fail("point id " + std::to_string(pid) + " (twice)");
      p.desc.assign(d, d + mi.descriptor_bytes);
      p.obs.reserve(static_cast<size_t>(n_obs));
    }
    for (int64_t o = 0; o < n_obs; ++o) {
      const int64_t kf = r.count("observation keyframe", 0, h.next_kf_id - 1);
      const int64_t feat = r.count("observation feature", 0, kMaxFeatures - 1);
      if (!map) continue;
      Keyframe* k = map->keyframe(static_cast<int>(kf));
      if (!k)
        r.fail("observation of point " + std::to_string(pid) + ": keyframe " + std::to_string(kf) +
               " is not in the map");
      if (feat >= k->features.count) {
        r.fail("observation of point " + std::to_string(pid) + ": feature " + std::to_string(feat) +
               " of keyframe " + std::to_string(kf) + " (it has " +
               std::to_string(k->features.count) + ")");
      }
      if (k->point_of[size_t(feat)] >= 0) {
        r.fail("observation of point " + std::to_string(pid) + ": feature " + std::to_string(feat) +
               " of keyframe " + std::to_string(kf) + " already holds point " +
               std::to_string(k->point_of[size_t(feat)]));
      }
      for (const auto& q : p.obs) {
        if (q.kf == kf)
          r.fail("point " + std::to_string(pid) + ": two observations in keyframe " +
                 std::to_string(kf));
      }
      k->point_of[size_t(feat)] = pid;
      p.obs.push_back({static_cast<int>(kf), static_cast<int>(feat)});
    }
    const int64_t first = r.count("point first keyframe", -1, h.next_kf_id - 1);
    p.first_kf = static_cast<int>(first >= 0 ? first : (p.obs.empty() ? -1 : p.obs.front().kf));
    if (map && first >= 0 && !map->keyframe(static_cast<int>(first))) {
      r.fail("point " + std::to_string(pid) + " first keyframe " + std::to_string(first));
    }
    p.created_kf_seq = static_cast<int>(r.count("point creation", INT32_MIN / 2, h.kf_seq));
    p.normal = r.vec3("point normal");
    p.min_dist = r.pod<float>("point distance range");
    p.max_dist = r.pod<float>("point distance range");
    if (!std::isfinite(p.min_dist) || !std::isfinite(p.max_dist) || p.min_dist < 0 ||
        p.max_dist < p.min_dist) {
      r.fail("point " + std::to_string(pid) + " distance range");
    }
    p.missed = r.pod<int32_t>("point counter");
    p.moved = r.pod<int32_t>("point counter");
    p.unmatched = r.pod<int32_t>("point counter");
    if (map) map->points.emplace(pid, std::move(p));
  }
  if (r.left() != 0) r.fail("payload: " + std::to_string(r.left()) + " bytes after the last point");
  if (map) {
    map->next_point_id = h.next_point_id;
    map->next_kf_id = static_cast<int>(h.next_kf_id);
    map->kf_seq = static_cast<int>(h.kf_seq);
    bool any_fixed = false;
    for (const auto& kv : map->keyframes) any_fixed |= kv.second.fixed;
    if (!any_fixed && !map->keyframes.empty()) map->keyframes.begin()->second.fixed = true;
  }
}

}  // namespace

Map decode_map(const std::vector<uint8_t>& bytes, MapInfo* info) {
  Reader r = open_payload(bytes);
  Header h = read_header(r);
  Map map;
  read_body(r, h, &map);
  h.info.file_bytes = bytes.size();
  if (info) *info = h.info;
  return map;
}

MapInfo decode_map_info(const std::vector<uint8_t>& bytes) {
  Reader r = open_payload(bytes);
  Header h = read_header(r);
  read_body(r, h, nullptr);
  h.info.file_bytes = bytes.size();
  return h.info;
}

std::string check_map_compatible(const MapInfo& info, const CameraModel& camera,
                                 const FeatureParams& features) {
  auto num = [](double v) {
    char b[32];
    std::snprintf(b, sizeof(b), "%g", v);
    return std::string(b);
  };
  const CameraModel& m = info.camera;
  if (info.feature_mode != features.mode) {
    return "map made with feature mode " + info.feature_mode + ", this run uses " + features.mode +
           " (features.mode)";
  }
  if (m.model != camera.model) {
    return "map made with camera model " + m.model + ", this run uses " + camera.model +
           " (camera.model)";
  }
  if (m.width != camera.width || m.height != camera.height) {
    return "map made with image size " + std::to_string(m.width) + "x" + std::to_string(m.height) +
           ", this run uses " + std::to_string(camera.width) + "x" + std::to_string(camera.height);
  }
  const std::pair<const char*, std::pair<double, double>> fields[] = {
      {"fx", {m.fx, camera.fx}}, {"fy", {m.fy, camera.fy}}, {"cx", {m.cx, camera.cx}},
      {"cy", {m.cy, camera.cy}}, {"k1", {m.k1, camera.k1}}, {"k2", {m.k2, camera.k2}},
      {"p1", {m.p1, camera.p1}}, {"p2", {m.p2, camera.p2}}, {"k3", {m.k3, camera.k3}},
      {"k4", {m.k4, camera.k4}}};
  for (const auto& [name, v] : fields) {
    if (std::abs(v.first - v.second) > 1e-9 * std::max(1.0, std::abs(v.second))) {
      return std::string("map made with camera.") + name + " = " + num(v.first) +
             ", this run uses " + num(v.second);
    }
  }
  return {};
}

std::vector<uint8_t> read_map_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_io("map: cannot open", path, errno);
  std::vector<uint8_t> out;
  struct stat st {};
  if (::fstat(fd, &st) == 0 && st.st_size > 0) out.reserve(static_cast<size_t>(st.st_size));
  uint8_t buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      fail_io("map: cannot read", path, e);
    }
    if (n == 0) break;
    out.insert(out.end(), buf, buf + n);
  }
  ::close(fd);
  return out;
}

void write_map_file_atomic(const std::string& path, const std::vector<uint8_t>& bytes, int keep) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail_io("map: cannot create", tmp, errno);
  size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : EIO;
      ::close(fd);
      ::unlink(tmp.c_str());
      fail_io("map: cannot write", tmp, e);
    }
    off += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    fail_io("map: fsync failed on", tmp, e);
  }
  if (::close(fd) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    fail_io("map: cannot close", tmp, e);
  }
  // Keep the previous versions: FILE.(k-1) -> FILE.k, then FILE linked as FILE.1 (FILE stays).
  if (keep > 1 && ::access(path.c_str(), F_OK) == 0) {
    for (int k = keep - 1; k >= 2; --k) {
      const std::string from = path + "." + std::to_string(k - 1);
      const std::string to = path + "." + std::to_string(k);
      if (::access(from.c_str(), F_OK) == 0) ::rename(from.c_str(), to.c_str());
    }
    const std::string first = path + ".1";
    ::unlink(first.c_str());
    if (::link(path.c_str(), first.c_str()) != 0) {
      const int e = errno;
      ::unlink(tmp.c_str());
      fail_io("map: cannot keep the previous map as", first, e);
    }
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    fail_io("map: cannot rename the new map to", path, e);
  }
  const std::string dir = dir_of(path);
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);  // the rename itself is durable
    ::close(dfd);
  }
}

}  // namespace rdslam
