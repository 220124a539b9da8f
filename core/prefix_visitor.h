// A ParamVisitor adapter that prefixes every key ("init_" + "min_matches"), so a parameter
// struct nested inside another (InitializerParams in TrackerParams, BundleAdjustmentParams in
// MapperParams) appears as flat keys of its parent's config section.
//
// Ownership: refers to the wrapped visitor for its lifetime. Threads: start-up.
#pragma once

#include <string>
#include <vector>

#include "core/params.h"

namespace rdslam {

class PrefixVisitor : public ParamVisitor {
 public:
  PrefixVisitor(ParamVisitor& inner, const char* prefix) : inner_(inner), prefix_(prefix) {}
  void field(const char* key, int& value, int lo, int hi, const char* doc) override {
    inner_.field((prefix_ + key).c_str(), value, lo, hi, doc);
  }
  void field(const char* key, double& value, double lo, double hi, const char* doc) override {
    inner_.field((prefix_ + key).c_str(), value, lo, hi, doc);
  }
  void field(const char* key, bool& value, const char* doc) override {
    inner_.field((prefix_ + key).c_str(), value, doc);
  }
  void field(const char* key, std::string& value, const std::vector<std::string>& allowed,
             const char* doc) override {
    inner_.field((prefix_ + key).c_str(), value, allowed, doc);
  }
  void field(const char* key, std::vector<int>& value, int lo, int hi, const char* doc) override {
    inner_.field((prefix_ + key).c_str(), value, lo, hi, doc);
  }

 private:
  ParamVisitor& inner_;
  std::string prefix_;
};

}  // namespace rdslam
