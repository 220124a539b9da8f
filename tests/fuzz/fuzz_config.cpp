// libFuzzer target: the configuration file and the --set overrides (firmware_app/config.h:
// yaml-cpp, then ParamVisitor's type and range checks and AppConfig::validate()). Input: the
// YAML text, optionally followed by a NUL byte and newline-separated "key=value" overrides.
// A bad file must end in ConfigError (a std::runtime_error naming key and value); anything
// else -- another exception, a crash, a sanitizer report -- is a bug.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "firmware_app/config.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const uint8_t* nul = static_cast<const uint8_t*>(std::memchr(data, 0, size));
  const size_t yaml_size = nul ? static_cast<size_t>(nul - data) : size;
  std::vector<std::string> overrides;
  if (nul) {
    std::stringstream ss(
        std::string(reinterpret_cast<const char*>(nul + 1), data + size - nul - 1));
    for (std::string line; std::getline(ss, line);) overrides.push_back(line);
  }
  const auto path = rdslam::fuzz::scratch_dir() / "config.yaml";
  rdslam::fuzz::write_file(path, data, yaml_size);
  try {
    rdslam::AppConfig cfg = rdslam::load_config(path.string(), overrides);
    (void)rdslam::dump_config(cfg);
  } catch (const rdslam::ConfigError&) {
  }
  return 0;
}
