// The place-recognition vocabulary (core/vocabulary.h): training finds planted clusters,
// transform is deterministic and survives a save/load round trip, the repository's vocabulary
// loads, and a missing, truncated or corrupt file is a clear error.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "core/features.h"
#include "core/vocabulary.h"

namespace rdslam {
namespace {

// `clusters` random 256-bit centres; each image holds `per` descriptors of each centre with
// up to `flips` random bits flipped (with `subsets`, image i leaves out the clusters c with
// (c + i) % 3 == 0, so words differ in document frequency).
std::vector<cv::Mat> planted(int clusters, int images, int per, int flips, uint64_t seed,
                             std::vector<cv::Mat>* centres_out = nullptr, bool subsets = false) {
  std::mt19937_64 rng(seed);
  cv::Mat centres(clusters, 32, CV_8U);
  for (int c = 0; c < clusters; ++c) {
    for (int b = 0; b < 32; ++b) centres.at<uint8_t>(c, b) = static_cast<uint8_t>(rng());
  }
  if (centres_out) centres_out->assign(1, centres);
  std::vector<cv::Mat> out;
  for (int im = 0; im < images; ++im) {
    cv::Mat m(clusters * per, 32, CV_8U);
    for (int c = 0; c < clusters; ++c) {
      for (int k = 0; k < per; ++k) {
        uint8_t* row = m.ptr<uint8_t>(c * per + k);
        std::copy(centres.ptr<uint8_t>(c), centres.ptr<uint8_t>(c) + 32, row);
        const int nf = static_cast<int>(rng() % (flips + 1));
        for (int f = 0; f < nf; ++f) {
          const int bit = static_cast<int>(rng() % 256);
          row[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        }
      }
    }
    if (subsets) {
      cv::Mat kept(0, 32, CV_8U);
      for (int c = 0; c < clusters; ++c) {
        if ((c + im) % 3 != 0) kept.push_back(m.rowRange(c * per, (c + 1) * per));
      }
      m = kept;
    }
    out.push_back(m);
  }
  return out;
}

std::string temp_path(const char* name) {
  return ::testing::TempDir() + "/rdslam_vocab_" + name + ".bin";
}

std::vector<uint8_t> read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)),
                              std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& p, const std::vector<uint8_t>& b) {
  std::ofstream f(p, std::ios::binary);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

std::string load_error(const std::string& path) {
  try {
    Vocabulary::load(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(Vocabulary, TrainingSeparatesPlantedClusters) {
  // 8 clusters at k = 8, one level: each cluster's descriptors share one word, and different
  // clusters (random centres, ~128 bits apart) get different words.
  std::vector<cv::Mat> centres;
  const std::vector<cv::Mat> imgs = planted(8, 6, 20, 12, 7, &centres);
  Vocabulary::TrainParams p;
  p.k = 8;
  p.levels = 1;
  const Vocabulary v = Vocabulary::train(imgs, p);
  EXPECT_EQ(v.words(), 8);
  std::vector<int> word_of_cluster(8, -1);
  for (int c = 0; c < 8; ++c) {
    word_of_cluster[c] = v.transform(centres[0].ptr<uint8_t>(c));
    for (int k = 0; k < 20; ++k) {
      EXPECT_EQ(v.transform(imgs[3].ptr<uint8_t>(c * 20 + k)), word_of_cluster[c]) << c;
    }
  }
  std::sort(word_of_cluster.begin(), word_of_cluster.end());
  EXPECT_EQ(std::unique(word_of_cluster.begin(), word_of_cluster.end()), word_of_cluster.end());
  // Every word occurs in every image: idf = ln(6/6) = 0.
  for (int w = 0; w < v.words(); ++w) EXPECT_FLOAT_EQ(v.idf(w), 0.f);
}

TEST(Vocabulary, TransformIsDeterministicAndSurvivesSaveLoad) {
  const std::vector<cv::Mat> imgs = planted(40, 10, 8, 30, 3);
  Vocabulary::TrainParams p;
  p.k = 4;
  p.levels = 3;
  const Vocabulary a = Vocabulary::train(imgs, p);
  const Vocabulary b = Vocabulary::train(imgs, p);  // same seed: the same tree
  EXPECT_EQ(a.checksum(), b.checksum());
  EXPECT_LE(a.words(), 64);
  const std::string path = temp_path("roundtrip");
  a.save(path);
  const Vocabulary c = Vocabulary::load(path);
  EXPECT_EQ(c.checksum(), a.checksum());
  EXPECT_EQ(c.k(), 4);
  EXPECT_EQ(c.levels(), 3);
  const cv::Mat probe = planted(40, 1, 3, 60, 99)[0];
  for (int r = 0; r < probe.rows; ++r) {
    int na = -1, nc = -1;
    const int wa = a.transform(probe.ptr<uint8_t>(r), 2, &na);
    EXPECT_EQ(wa, a.transform(probe.ptr<uint8_t>(r)));  // repeatable
    EXPECT_EQ(c.transform(probe.ptr<uint8_t>(r), 2, &nc), wa);
    EXPECT_EQ(nc, na);
    EXPECT_GE(na, 0);
    EXPECT_LT(na, a.nodes());
  }
  std::remove(path.c_str());
}

TEST(Vocabulary, BowVectorIsSortedAndL1Normalised) {
  const std::vector<cv::Mat> imgs = planted(30, 10, 5, 20, 5, nullptr, true);
  Vocabulary::TrainParams p;
  p.k = 5;
  p.levels = 2;
  const Vocabulary v = Vocabulary::train(imgs, p);
  // The first 60 descriptors of one image (12 clusters x 5): at most 12 distinct words.
  BowVector bow;
  Vocabulary::Scratch s;
  std::vector<int> word_of(60);
  v.transform(imgs[2].data, imgs[2].step[0], 60, bow, s, word_of.data());
  ASSERT_GT(bow.size, 0);
  EXPECT_LE(bow.size, 12);
  double sum = 0;
  for (int i = 0; i < bow.size; ++i) {
    if (i > 0) {
      EXPECT_LT(bow.words[i - 1], bow.words[i]);
    }
    EXPECT_GT(bow.weights[i], 0.f);
    sum += bow.weights[i];
  }
  EXPECT_NEAR(sum, 1.0, 1e-5);
  for (int j = 0; j < 60; ++j) EXPECT_EQ(word_of[j], v.transform(imgs[2].ptr<uint8_t>(j)));
}

TEST(Vocabulary, RepositoryVocabularyLoads) {
  // data/vocab/orb_k10l4.bin (docs/place_recognition.md): k 10, 4 levels, nearly 10^4 words.
  const Vocabulary v =
      Vocabulary::load(std::string(RDSLAM_SOURCE_DIR) + "/data/vocab/orb_k10l4.bin");
  EXPECT_EQ(v.k(), 10);
  EXPECT_EQ(v.levels(), 4);
  EXPECT_GT(v.words(), 9000);
  EXPECT_LE(v.words(), 10000);
  EXPECT_EQ(v.nodes_at_level(1), 10);
  // Its words are used: ORB features of a textured image spread over many of them.
  cv::Mat img(480, 640, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  FeatureParams fp;
  FeatureExtractor fx(fp, CameraModel{});
  Features f;
  fx.extract(img, f);
  ASSERT_GT(f.count, 500);
  BowVector bow;
  Vocabulary::Scratch s;
  v.transform(f, bow, s);
  EXPECT_GT(bow.size, f.count / 4);
}

TEST(Vocabulary, MissingTruncatedOrCorruptFileIsAClearError) {
  EXPECT_NE(load_error("/nonexistent/orb.bin").find("cannot open"), std::string::npos);
  const std::vector<cv::Mat> imgs = planted(20, 4, 5, 10, 11);
  Vocabulary::TrainParams p;
  p.k = 4;
  p.levels = 2;
  const std::string path = temp_path("corrupt");
  Vocabulary::train(imgs, p).save(path);
  const std::vector<uint8_t> good = read_bytes(path);
  ASSERT_GT(good.size(), 100u);

  std::vector<uint8_t> b = good;
  b[good.size() / 2] ^= 0x10;  // one flipped bit in a node
  write_bytes(path, b);
  const std::string flipped = load_error(path);
  EXPECT_NE(flipped.find("checksum mismatch"), std::string::npos) << flipped;
  EXPECT_NE(flipped.find(path), std::string::npos) << "names the file: " << flipped;

  b.assign(good.begin(), good.end() - 9);  // truncated
  write_bytes(path, b);
  EXPECT_NE(load_error(path).find("truncated"), std::string::npos) << load_error(path);

  b = good;
  b[0] = 'X';  // not a vocabulary
  write_bytes(path, b);
  EXPECT_NE(load_error(path).find("bad magic"), std::string::npos) << load_error(path);

  write_bytes(path, good);
  EXPECT_EQ(load_error(path), "");
  std::remove(path.c_str());
}

}  // namespace
}  // namespace rdslam
