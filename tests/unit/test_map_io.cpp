// Map files (core/map_io.h): round trip, what is not saved, every kind of damage refused with a
// clear message, camera / feature-mode mismatches, atomic writes that leave the previous file
// when they fail, kept versions, the mapper's load/save, and saves while running (a copy on
// the mapper thread, written by the writer thread of firmware_app/map_writer.h).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include "core/keyframe.h"
#include "core/map_io.h"
#include "core/mapper.h"
#include "firmware_app/map_writer.h"
#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;
using testing::ScratchDir;

constexpr int kFeatures = 80;

// A map of `n_kf` keyframes (features with random ORB descriptors, a BGR image), points seen
// by consecutive keyframe pairs (n_pt <= 40 x n_kf); keyframe 2 (when there) and point 3 are
// invalid.
Map make_map(int n_kf = 4, int n_pt = 60) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 600.f);
  Map m;
  for (int k = 0; k < n_kf; ++k) {
    Keyframe& kf = m.keyframes[k];
    kf.id = k;
    kf.stamp_ns = 1000000000LL + k * 33000000LL;
    kf.T_cam_world.R = Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitY()).toRotationMatrix();
    kf.T_cam_world.t = Eigen::Vector3d(0.1 * k, -0.05 * k, 0.02);
    kf.fixed = k == 0;
    kf.valid = k != 2;
    Features& f = kf.features;
    f.count = kFeatures;
    f.width = 640;
    f.height = 480;
    f.cell_px = 20.f;
    f.kps.resize(kFeatures);
    f.un.resize(kFeatures);
    f.scale.resize(kFeatures);
    f.level.resize(kFeatures);
    f.desc.create(kFeatures, 32, CV_8U);
    for (int i = 0; i < kFeatures; ++i) {
      f.kps[i] = cv::KeyPoint(u(rng), u(rng) * 0.75f, 31.f, u(rng) * 0.6f, 0.5f, i % 4);
      f.un[i] = f.kps[i].pt + cv::Point2f(0.25f, -0.5f);
      f.level[i] = i % 4;
      f.scale[i] = std::pow(1.2f, float(i % 4));
      for (int b = 0; b < 32; ++b) f.desc.at<uint8_t>(i, b) = static_cast<uint8_t>(rng());
    }
    f.build_grid();
    kf.point_of.assign(kFeatures, -1);
    kf.image.create(480, 640, CV_8UC3);
    cv::randu(kf.image, 0, 255);
  }
  for (int i = 0; i < n_pt; ++i) {
    MapPoint& p = m.points[i];
    p.id = i;
    p.p_world = Eigen::Vector3d(0.01 * i, -0.02 * i, 2.0 + 0.01 * i);
    p.desc.assign(32, static_cast<uint8_t>(i));
    p.valid = i != 3;
    p.first_kf = i % n_kf;
    p.created_kf_seq = 1;
    p.normal = Eigen::Vector3d(0, 0.6, 0.8);
    p.min_dist = 0.5f;
    p.max_dist = 4.0f + i;
    p.missed = i % 3;
    p.moved = i % 2;
    // Even features: first observations, odd ones: second (no two points on one feature).
    EXPECT_TRUE(m.add_observation(i, i % n_kf, 2 * (i / n_kf)));
    EXPECT_TRUE(m.add_observation(i, (i + 1) % n_kf, 2 * (i / n_kf) + 1));
  }
  m.next_point_id = n_pt + 5;
  m.next_kf_id = n_kf + 1;
  m.kf_seq = n_kf + 2;
  return m;
}

CameraModel camera() {
  return CameraModel{};
}  // 640x480, f 525, pinhole-radtan
FeatureParams orb() {
  return FeatureParams{};
}

std::vector<uint8_t> encoded(const Map& m) {
  return encode_map(m, camera(), orb());
}

std::string decode_error(const std::vector<uint8_t>& bytes) {
  try {
    decode_map(bytes);
  } catch (const MapFormatError& e) {
    return e.what();
  }
  return "";
}

TEST(MapIo, RoundTripKeepsValidKeyframesAndPoints) {
  const Map m = make_map();
  MapInfo wi;
  const std::vector<uint8_t> bytes = encode_map(m, camera(), orb(), &wi);
  MapInfo ri;
  const Map d = decode_map(bytes, &ri);
  // Keyframe 2 is invalid: not saved. Points seen by it and one other keyframe keep only one
  // observation: not saved either; point 3 is invalid.
  ASSERT_EQ(d.keyframes.size(), 3u);
  EXPECT_EQ(d.keyframes.count(2), 0u);
  size_t expect_points = 0;
  for (const auto& [pid, p] : m.points) {
    int kept = 0;
    for (const auto& o : p.obs) kept += o.kf != 2;
    const bool saved = p.valid && kept >= 2;
    expect_points += saved;
    ASSERT_EQ(d.points.count(pid), saved ? 1u : 0u) << pid;
    if (!saved) continue;
    const MapPoint& q = d.points.at(pid);
    EXPECT_EQ(q.p_world, p.p_world);
    EXPECT_EQ(q.desc, p.desc);
    EXPECT_EQ(q.normal, p.normal);
    EXPECT_EQ(q.min_dist, p.min_dist);
    EXPECT_EQ(q.max_dist, p.max_dist);
    EXPECT_EQ(q.first_kf, p.first_kf);
    EXPECT_EQ(q.missed, p.missed);
    EXPECT_EQ(q.moved, p.moved);
    ASSERT_EQ(q.obs.size(), p.obs.size());
    for (size_t o = 0; o < q.obs.size(); ++o) {
      EXPECT_EQ(q.obs[o].kf, p.obs[o].kf);
      EXPECT_EQ(q.obs[o].feat, p.obs[o].feat);
      EXPECT_EQ(d.keyframes.at(q.obs[o].kf).point_of[size_t(q.obs[o].feat)], pid);
    }
  }
  EXPECT_GT(expect_points, 20u);
  EXPECT_EQ(d.points.size(), expect_points);
  for (const auto& [id, k] : d.keyframes) {
    const Keyframe& o = m.keyframes.at(id);
    EXPECT_EQ(k.stamp_ns, o.stamp_ns);
    EXPECT_EQ(k.fixed, o.fixed);
    EXPECT_TRUE(k.T_cam_world.R.isApprox(o.T_cam_world.R, 0.0));
    EXPECT_EQ(k.T_cam_world.t, o.T_cam_world.t);
    ASSERT_EQ(k.features.count, o.features.count);
    for (int i = 0; i < k.features.count; ++i) {
      EXPECT_EQ(k.features.kps[i].pt, o.features.kps[i].pt);
      EXPECT_EQ(k.features.kps[i].octave, o.features.kps[i].octave);
      EXPECT_EQ(k.features.un[i], o.features.un[i]);
      EXPECT_EQ(k.features.level[i], o.features.level[i]);
      EXPECT_EQ(k.features.scale[i], o.features.scale[i]);
      EXPECT_EQ(0, std::memcmp(k.features.desc_ptr(i), o.features.desc_ptr(i), 32));
    }
    // The grid is rebuilt: a radius search finds a feature at its own position.
    int found[64];
    const cv::Point2f x = k.features.un[5];
    const int n = k.features.radius_search(x.x, x.y, 1.f, -1, 99, found, 64);
    EXPECT_NE(std::find(found, found + n, 5), found + n);
    // The image is lossless (PNG).
    ASSERT_EQ(k.image.size(), o.image.size());
    EXPECT_EQ(cv::norm(k.image, o.image, cv::NORM_INF), 0.0);
  }
  EXPECT_EQ(d.next_point_id, m.next_point_id);
  EXPECT_EQ(d.next_kf_id, m.next_kf_id);
  EXPECT_EQ(d.kf_seq, m.kf_seq);
  EXPECT_EQ(ri.keyframes, 3);
  EXPECT_EQ(ri.points, static_cast<int>(expect_points));
  EXPECT_EQ(ri.observations, wi.observations);
  EXPECT_EQ(ri.images, 3);
  EXPECT_EQ(ri.feature_mode, "orb");
  EXPECT_EQ(ri.camera.fx, 525.0);
  const MapInfo only = decode_map_info(bytes);
  EXPECT_EQ(only.points, ri.points);
  EXPECT_EQ(only.file_bytes, bytes.size());
  // Deterministic: the same map encodes to the same bytes (but for the save time).
  std::vector<uint8_t> again = encoded(m);
  ASSERT_EQ(again.size(), bytes.size());
}

TEST(MapIo, TruncatedMapsAreRefused) {
  const std::vector<uint8_t> bytes = encoded(make_map());
  for (size_t keep : {size_t(0), size_t(10), size_t(23), size_t(24), size_t(200), bytes.size() / 2,
                      bytes.size() - 1}) {
    std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(keep));
    const std::string e = decode_error(cut);
    EXPECT_NE(e.find("truncated"), std::string::npos) << keep << ": " << e;
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_NE(decode_error(longer).find("trailing bytes"), std::string::npos);
}

TEST(MapIo, EveryFlippedBitIsRefused) {
  const std::vector<uint8_t> bytes = encoded(make_map(3, 20));
  std::mt19937 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> bad = bytes;
    const size_t at = 24 + rng() % (bytes.size() - 24);  // in the payload
    bad[at] ^= static_cast<uint8_t>(1u << (rng() % 8));
    const std::string e = decode_error(bad);
    EXPECT_NE(e.find("checksum mismatch"), std::string::npos) << at << ": " << e;
  }
  // The preamble: magic, version, size, checksum.
  for (size_t at : {size_t(0), size_t(8), size_t(13), size_t(21)}) {
    std::vector<uint8_t> bad = bytes;
    bad[at] ^= 0x10;
    EXPECT_FALSE(decode_error(bad).empty()) << at;
  }
}

TEST(MapIo, WrongVersionAndMagicNameTheProblem) {
  std::vector<uint8_t> bytes = encoded(make_map(3, 20));
  std::vector<uint8_t> v2 = bytes;
  v2[8] = 2;
  EXPECT_EQ(decode_error(v2), "map: format version 2, this rdslam reads version 1");
  std::vector<uint8_t> magic = bytes;
  magic[0] = 'X';
  EXPECT_EQ(decode_error(magic), "map: not an rdslam map file (bad magic)");
}

TEST(MapIo, ChecksummedButInconsistentContentIsRefused) {
  // A payload that passes the CRC but whose indices are wrong (as a buggy writer would make):
  // an observation of a feature the keyframe does not have.
  Map m = make_map(3, 20);
  m.points.at(0).obs[0].feat = kFeatures + 3;
  const std::string e = decode_error(encoded(m));
  EXPECT_NE(e.find("feature 83 of keyframe 0 (it has 80)"), std::string::npos) << e;
  Map dup = make_map(3, 20);
  dup.points.at(1).obs[1] = dup.points.at(0).obs[0];  // two points on one feature
  EXPECT_NE(decode_error(encoded(dup)).find("already holds point"), std::string::npos);
}

TEST(MapIo, OtherCameraOrFeatureModeIsRefusedNamingBothValues) {
  const MapInfo info = decode_map_info(encoded(make_map(3, 20)));
  EXPECT_EQ(check_map_compatible(info, camera(), orb()), "");
  CameraModel c = camera();
  c.fx = 500;
  EXPECT_EQ(check_map_compatible(info, c, orb()),
            "map made with camera.fx = 525, this run uses 500");
  c = camera();
  c.model = "pinhole-equidistant";
  EXPECT_EQ(check_map_compatible(info, c, orb()),
            "map made with camera model pinhole-radtan, this run uses pinhole-equidistant "
            "(camera.model)");
  c = camera();
  c.width = 1280;
  EXPECT_EQ(check_map_compatible(info, c, orb()),
            "map made with image size 640x480, this run uses 1280x480");
  FeatureParams sift;
  sift.mode = "sift";
  EXPECT_EQ(check_map_compatible(info, camera(), sift),
            "map made with feature mode orb, this run uses sift (features.mode)");
}

TEST(MapIo, FailedWriteLeavesThePreviousFile) {
  ScratchDir dir("mapio");
  const std::string path = (dir.path() / "room.map").string();
  const std::vector<uint8_t> small = encoded(make_map(3, 20));
  write_map_file_atomic(path, small);
  ASSERT_EQ(read_map_file(path), small);
  // A write that fails half-way (file size limit: EFBIG even for root).
  const std::vector<uint8_t> big = encoded(make_map(6, 200));
  ASSERT_GT(big.size(), small.size() + 4096);
  rlimit old{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
  signal(SIGXFSZ, SIG_IGN);
  rlimit lim = old;
  lim.rlim_cur = small.size() + 4096;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &lim), 0);
  std::string err;
  try {
    write_map_file_atomic(path, big);
  } catch (const MapFormatError& e) {
    err = e.what();
  }
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &old), 0);
  signal(SIGXFSZ, SIG_DFL);
  EXPECT_NE(err.find("cannot write"), std::string::npos) << err;
  EXPECT_EQ(read_map_file(path), small);  // untouched and still valid
  EXPECT_NO_THROW(decode_map(read_map_file(path)));
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1);  // no temporary file left
  // An unwritable directory.
  EXPECT_THROW(write_map_file_atomic((dir.path() / "no/such/dir.map").string(), small),
               MapFormatError);
  EXPECT_THROW(read_map_file((dir.path() / "missing.map").string()), MapFormatError);
}

TEST(MapIo, KeepsTheLastVersions) {
  ScratchDir dir("mapio");
  const std::string path = (dir.path() / "room.map").string();
  std::vector<std::vector<uint8_t>> versions;
  for (int v = 0; v < 4; ++v) {
    versions.push_back(encoded(make_map(3, 10 + 5 * v)));
    write_map_file_atomic(path, versions.back(), 3);
  }
  EXPECT_EQ(read_map_file(path), versions[3]);
  EXPECT_EQ(read_map_file(path + ".1"), versions[2]);
  EXPECT_EQ(read_map_file(path + ".2"), versions[1]);
  EXPECT_FALSE(fs::exists(path + ".3"));
}

TEST(MapIo, MapperLoadsPublishesAndSavesTheMap) {
  // The mapper publishes a loaded map to the tracker (valid points with >= 2 observations) and
  // saves it back unchanged.
  const Map m = make_map();
  const std::vector<uint8_t> bytes = encoded(m);
  Map loaded = decode_map(bytes);
  const size_t n_points = loaded.points.size();
  auto link = std::make_shared<SlamLink>(2);
  Mapper mapper(MapperParams{}, orb(), camera(), link);
  mapper.load(std::move(loaded));
  const auto snap = link->index.acquire();
  ASSERT_TRUE(snap);
  EXPECT_EQ(snap->epoch, 0u);
  EXPECT_EQ(snap->rows(), static_cast<int>(n_points));
  EXPECT_EQ(snap->kf_ids.size(), 3u);
  ScratchDir dir("mapio");
  const std::string path = (dir.path() / "again.map").string();
  std::string err;
  ASSERT_TRUE(mapper.save(path, 1, &err)) << err;
  const Map again = decode_map(read_map_file(path));
  EXPECT_EQ(again.points.size(), n_points);
  EXPECT_EQ(again.keyframes.size(), 3u);
  // A save request is served by the mapper's next step; a failing one is counted.
  mapper.set_save_target((dir.path() / "no/such/dir.map").string(), 1);
  link->save_requests.fetch_add(1);
  mapper.step(0);
  EXPECT_EQ(link->saves_failed.load(), 1u);
  mapper.set_save_target(path, 2);
  link->save_requests.fetch_add(1);
  mapper.step(0);
  EXPECT_EQ(link->saves_done.load(), 1u);
  EXPECT_TRUE(fs::exists(path + ".1"));
}

TEST(MapIo, CopyForSaveEncodesToTheSameBytesAndSharesNothing) {
  // A save while running encodes a copy on another thread (core/mapper.h MapSaveWriter): the
  // copy must give the file the map itself gives, and stay so while the owner changes the map.
  Map m = make_map(5, 120);
  constexpr int64_t kSaved = 1700000000;
  const std::vector<uint8_t> direct = encode_map(m, camera(), orb(), nullptr, kSaved);
  const Map copy = copy_map_for_save(m);
  EXPECT_EQ(copy.keyframes.size(), 4u);  // keyframe 2 is invalid: not copied
  EXPECT_LT(copy.points.size(), m.points.size());
  EXPECT_EQ(encode_map(copy, camera(), orb(), nullptr, kSaved), direct);
  // The owner writes into its buffers in place (Features::copy_from, Mat::copyTo reuse them).
  for (auto& [id, kf] : m.keyframes) {
    kf.image.setTo(cv::Scalar::all(id));
    kf.features.desc.setTo(cv::Scalar::all(0xA5));
    kf.features.kps[0].pt.x += 3.f;
    kf.T_cam_world.t.x() += 1.0;
  }
  for (auto& [id, p] : m.points) {
    p.desc.assign(32, 0);
    p.p_world.z() += 1.0;
  }
  m.erase_keyframe(1);
  EXPECT_NE(encode_map(m, camera(), orb(), nullptr, kSaved), direct);
  EXPECT_EQ(encode_map(copy, camera(), orb(), nullptr, kSaved), direct);
}

// A writer that keeps the job (the test runs it when it chooses).
class HeldWriter : public MapSaveWriter {
 public:
  bool busy() const override { return job != nullptr; }
  void submit(std::unique_ptr<MapSaveJob> j) override {
    ++submitted;
    job = std::move(j);
  }
  std::unique_ptr<MapSaveJob> job;
  int submitted = 0;
};

// A mapper holding make_map() (as loaded from its file), saving to `name` in a scratch directory
// through `writer`, with one save requested and the mapper's step that serves it done.
struct SavingMapper {
  SavingMapper(const char* name, MapSaveWriter* writer)
      : m(make_map()),
        link(std::make_shared<SlamLink>(2)),
        mapper(MapperParams{}, orb(), camera(), link),
        dir("mapio"),
        path((dir.path() / name).string()) {
    mapper.load(decode_map(encoded(m)));
    mapper.set_save_target(path, 1);
    mapper.set_save_writer(writer);
    link->save_requests.fetch_add(1);
    mapper.step(0);
  }
  const Map m;
  std::shared_ptr<SlamLink> link;
  Mapper mapper;
  ScratchDir dir;
  const std::string path;
};

TEST(MapIo, MapperHandsSavesToTheWriterAndCoalescesRequestsWhileItIsBusy) {
  HeldWriter writer;
  SavingMapper sm("bg.map", &writer);
  const Map& m = sm.m;
  const auto& link = sm.link;
  Mapper& mapper = sm.mapper;
  const std::string& path = sm.path;
  ASSERT_EQ(writer.submitted, 1);
  EXPECT_FALSE(fs::exists(path));  // the mapper thread only copied the map
  EXPECT_EQ(writer.job->path, path);
  EXPECT_EQ(writer.job->link, link);
  // Three requests while the writer is busy: none is served yet...
  for (int i = 0; i < 3; ++i) link->save_requests.fetch_add(1);
  mapper.step(0);
  mapper.step(0);
  EXPECT_EQ(writer.submitted, 1);
  // ...the writer's thread writes the first copy: the file a save on the mapper thread makes.
  ASSERT_TRUE(run_map_save_job(*writer.job));
  EXPECT_EQ(link->saves_done.load(), 1u);
  const std::vector<uint8_t> written = read_map_file(path);
  const int64_t saved = decode_map_info(written).saved_unix_s;
  EXPECT_EQ(saved, writer.job->saved_unix_s);
  EXPECT_EQ(written, encode_map(decode_map(encoded(m)), camera(), orb(), nullptr, saved));
  // ...and once it is free, one copy serves the three waiting requests.
  writer.job.reset();
  mapper.step(0);
  EXPECT_EQ(writer.submitted, 2);
  EXPECT_EQ(link->saves_coalesced.load(), 2u);
  mapper.step(0);
  EXPECT_EQ(writer.submitted, 2);
  // A job that cannot be written is counted as failed.
  writer.job->path = (sm.dir.path() / "no/such/dir.map").string();
  EXPECT_FALSE(run_map_save_job(*writer.job));
  EXPECT_EQ(link->saves_failed.load(), 1u);
}

TEST(MapIo, MapWriterThreadWritesTheMappersCopyAndFinishesItOnStop) {
  // `rdslam run`'s writer thread (firmware_app/map_writer.h) behind the mapper: a request makes
  // a copy, the thread writes it, stop() waits for the write.
  MapWriter writer({}, 19);
  SavingMapper sm("thread.map", &writer);
  writer.stop();
  const auto& link = sm.link;
  EXPECT_FALSE(writer.busy());
  EXPECT_EQ(writer.jobs_run(), 1u);
  EXPECT_EQ(link->saves_done.load(), 1u);
  const std::vector<uint8_t> written = read_map_file(sm.path);
  EXPECT_EQ(written, encode_map(decode_map(encoded(sm.m)), camera(), orb(), nullptr,
                                decode_map_info(written).saved_unix_s));
}

}  // namespace
}  // namespace rdslam
