// Parameter reflection: every parameter struct in rdslam describes its fields once, in a
// `void visit(ParamVisitor& v)` member, with key, default (the member initialiser), allowed
// range and a one-line doc. The same description loads the struct from YAML, applies
// `--set key=value` overrides, validates ranges and prints what ran (OpenVINS style).
//
// Ownership: a ParamVisitor only reads/writes the fields it is handed during visit().
// Threads: used at start-up, from the thread that loads the configuration.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rdslam {

class ParamVisitor {
 public:
  virtual ~ParamVisitor() = default;
  // Integer field; allowed range [lo, hi].
  virtual void field(const char* key, int& value, int lo, int hi, const char* doc) = 0;
  // Floating-point field; allowed range [lo, hi].
  virtual void field(const char* key, double& value, double lo, double hi, const char* doc) = 0;
  virtual void field(const char* key, bool& value, const char* doc) = 0;
  // String field; `allowed` lists the accepted values, empty means any string.
  virtual void field(const char* key, std::string& value, const std::vector<std::string>& allowed,
                     const char* doc) = 0;
  // List of integers (e.g. CPU cores); each element in [lo, hi].
  virtual void field(const char* key, std::vector<int>& value, int lo, int hi, const char* doc) = 0;
};

}  // namespace rdslam
