// `rdslam vocab`: the place-recognition vocabulary (core/vocabulary.h,
// docs/place_recognition.md).
//   train   hierarchical k-medians over the ORB descriptors of frames of frame sources
//   info    a vocabulary file's shape and checksum
//   recall  place recognition on a sequence: every N-th frame is a keyframe in a database
//           (core/keyframe_database.h), the frames half-way between them are queries; a query
//           is recalled when its best candidate is one of the two keyframes around it
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <string>
#include <vector>

#include "core/features.h"
#include "core/keyframe_database.h"
#include "core/vocabulary.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {
namespace {

int positive_int(double v, const char* what) {
  if (v < 1 || v != std::floor(v)) throw UsageError(std::string(what) + " must be >= 1");
  return static_cast<int>(v);
}

// Calls on(frame index, features) for every `every`-th frame of `uri`, at most `max_frames`.
template <class On>
void for_features(const std::string& uri, int every, int max_frames, On&& on) {
  SourceOptions so;
  so.speed = 0.0;  // lossless, as fast as possible
  std::unique_ptr<FrameSource> src = open_source(uri, so);
  Frame frame;
  std::unique_ptr<FeatureExtractor> fx;
  FeatureParams fp;  // the defaults: ORB, 1200 features
  Features f;
  cv::Mat gray;
  int used = 0;
  for (int i = 0; used < max_frames; ++i) {
    const SourceStatus st = src->read(frame, 2000);
    if (st == SourceStatus::kEndOfStream) break;
    if (st != SourceStatus::kOk || i % every != 0) continue;
    const cv::Mat* img = &frame.image;
    if (frame.image.channels() == 3) {
      cv::cvtColor(frame.image, gray, cv::COLOR_BGR2GRAY);
      img = &gray;
    }
    if (!fx) {
      // A source's calibration when it fits the images, else an ideal pinhole of their size.
      CameraModel cam;
      cam.width = img->cols;
      cam.height = img->rows;
      cam.cx = (cam.width - 1) * 0.5;
      cam.cy = (cam.height - 1) * 0.5;
      const auto c = src->camera();
      if (c && c->width == cam.width && c->height == cam.height) cam = *c;
      fx = std::make_unique<FeatureExtractor>(fp, cam);
    }
    fx->extract(*img, f);
    on(i, f);
    ++used;
  }
}

int vocab_train(int argc, char** argv) {
  std::string out;
  std::vector<std::string> sources;
  double k = 10, levels = 4, every = 10, frames = 30, seed = 1;
  ArgParser p(
      "rdslam vocab train --out FILE --source URI [--source URI ...] [--k K] [--levels L]\n"
      "       [--every N] [--frames M] [--seed S]",
      "Train an ORB vocabulary: hierarchical k-medians (k-means++ seeding, majority bits) over\n"
      "the descriptors (default ORB features, 1200 per frame) of every N-th frame, at most M\n"
      "frames per source; idf weights from those frames. docs/place_recognition.md has the\n"
      "command that made data/vocab/orb_k10l4.bin.");
  p.option("--out", &out, "FILE", "vocabulary file to write");
  p.repeated("--source", &sources, "URI", "a frame source (synth:NAME?seed=S, video:FILE, ...)");
  p.option("--k", &k, "K", "children per node (default 10)");
  p.option("--levels", &levels, "L", "tree depth (default 4: at most K^L words)");
  p.option("--every", &every, "N", "use every N-th frame (default 10)");
  p.option("--frames", &frames, "M", "frames per source (default 30)");
  p.option("--seed", &seed, "S", "k-means++ seed (default 1)");
  if (!p.parse(argc, argv)) return 0;
  if (out.empty() || sources.empty()) throw UsageError("--out and at least one --source needed");
  std::vector<cv::Mat> images;
  size_t descriptors = 0;
  for (const std::string& uri : sources) {
    const size_t before = images.size();
    for_features(uri, positive_int(every, "--every"), positive_int(frames, "--frames"),
                 [&](int, const Features& f) {
                   images.push_back(f.desc.rowRange(0, f.count).clone());
                   descriptors += static_cast<size_t>(f.count);
                 });
    std::printf("%s: %zu frames\n", uri.c_str(), images.size() - before);
  }
  Vocabulary::TrainParams tp;
  tp.k = positive_int(k, "--k");
  tp.levels = positive_int(levels, "--levels");
  tp.seed = static_cast<uint64_t>(positive_int(seed, "--seed"));
  std::printf("training on %zu descriptors of %zu frames (k %d, levels %d)\n", descriptors,
              images.size(), tp.k, tp.levels);
  const Vocabulary v = Vocabulary::train(images, tp);
  v.save(out);
  std::printf("%s: %d words, %d nodes, checksum %016llx\n", out.c_str(), v.words(), v.nodes(),
              static_cast<unsigned long long>(v.checksum()));
  return 0;
}

int vocab_info(int argc, char** argv) {
  std::string path;
  ArgParser p("rdslam vocab info FILE", "Print a vocabulary's shape and checksum.");
  p.positional("FILE", &path, "vocabulary file");
  if (!p.parse(argc, argv)) return 0;
  const Vocabulary v = Vocabulary::load(path);
  std::printf("%s: k %d, levels %d, %d words, %d nodes, checksum %016llx\n", path.c_str(), v.k(),
              v.levels(), v.words(), v.nodes(), static_cast<unsigned long long>(v.checksum()));
  return 0;
}

int vocab_recall(int argc, char** argv) {
  std::string path, uri;
  double every = 10, frames = 1000;
  ArgParser p("rdslam vocab recall FILE --source URI [--every N] [--frames M]",
              "Place-recognition recall of a vocabulary on a sequence: every N-th frame is a\n"
              "keyframe, the frame half-way between two keyframes a query; recalled when the\n"
              "best candidate is one of those two keyframes.");
  p.positional("FILE", &path, "vocabulary file");
  p.option("--source", &uri, "URI", "frame source");
  p.option("--every", &every, "N", "keyframe spacing in frames (default 10, even)");
  p.option("--frames", &frames, "M", "frames to read (default 1000)");
  if (!p.parse(argc, argv)) return 0;
  if (uri.empty()) throw UsageError("--source URI needed");
  const int n = positive_int(every, "--every");
  if (n < 2 || n % 2 != 0) throw UsageError("--every must be even and >= 2");
  const Vocabulary v = Vocabulary::load(path);
  KeyframeDatabaseBuilder builder(v.words());
  std::vector<std::pair<int, BowVector>> queries;
  Vocabulary::Scratch scratch;
  for_features(uri, n / 2, positive_int(frames, "--frames"), [&](int i, const Features& f) {
    BowVector b;
    v.transform(f, b, scratch);
    if (i % n == 0) {
      builder.add(0, i, b);
    } else {
      queries.emplace_back(i, std::move(b));
    }
  });
  const auto db = builder.build();
  PlaceQueryScratch qs;
  PlaceQueryParams qp;
  qp.max_candidates = 1;
  int recalled = 0, asked = 0;
  for (const auto& [i, b] : queries) {
    if (i + n / 2 > (db->size() - 1) * n) continue;  // no keyframe after it
    PlaceCandidate c;
    ++asked;
    if (db->query(b, qp, qs, &c, 1) == 1 && std::abs(c.keyframe - i) <= n / 2) ++recalled;
  }
  std::printf("%s on %s: %d keyframes, %d queries, recall@1 %.3f\n", path.c_str(), uri.c_str(),
              db->size(), asked, asked ? double(recalled) / asked : 0.0);
  return 0;
}

const Subcommand kSubs[] = {
    {"train", "train an ORB vocabulary (hierarchical k-medians) on frame sources", vocab_train},
    {"info", "a vocabulary file's shape and checksum", vocab_info},
    {"recall", "place-recognition recall of a vocabulary on a sequence", vocab_recall},
};

}  // namespace

int cmd_vocab(int argc, char** argv) {
  return run_subcommand("vocab", "commands", kSubs, std::size(kSubs), argc, argv);
}

}  // namespace rdslam
