# Precompiled headers (CI wall time; numbers: docs/benchmarks.md, "CI wall time"). Included
# from the top-level CMakeLists.txt before the subdirectories.
#
# Every translation unit of the project parses the same OpenCV, Eigen and standard headers
# (about 1.1 s of CPU per file with GCC 12, before any code is generated); GoogleTest adds
# more to each test program. With RDSLAM_PCH these headers are compiled once per library
# (rdslam_core, rdslam_drivers, rdslam_app: each its own, their compile definitions differ)
# and once for all test programs (tests/CMakeLists.txt, REUSE_FROM), and force-included.
# Only third-party and standard headers are precompiled, so editing a project header does not
# rebuild a PCH; the sources still include what they use (`-DRDSLAM_PCH=OFF` builds them
# without, which is how a missing include shows).
#
# Default: ON, except with a ccache compiler launcher: ccache does not cache compilations
# that use a PCH unless told to be sloppy about it, and a warm ccache beats a PCH, so the
# development builds of docs/ (ccache) keep working as before. CI builds cold, without ccache.
set(_rdslam_pch_default ON)
if(CMAKE_CXX_COMPILER_LAUNCHER MATCHES "ccache")
  set(_rdslam_pch_default OFF)
endif()
option(RDSLAM_PCH "Precompile the common third-party and standard headers" ${_rdslam_pch_default})

# The headers most sources include (directly or through the project's headers).
set(RDSLAM_PCH_HEADERS
    <opencv2/core.hpp> <opencv2/imgproc.hpp> <Eigen/Core> <Eigen/Geometry> <algorithm> <array>
    <atomic> <chrono> <cmath> <cstdint> <cstdio> <cstdlib> <cstring> <filesystem> <fstream>
    <functional> <map> <memory> <mutex> <optional> <set> <sstream> <stdexcept> <string>
    <thread> <unordered_map> <vector>)

# rdslam_precompile_headers(target [extra headers...]): give target its own PCH of
# RDSLAM_PCH_HEADERS and the extra headers (nothing when RDSLAM_PCH is OFF).
function(rdslam_precompile_headers target)
  if(RDSLAM_PCH)
    target_precompile_headers(${target} PRIVATE ${RDSLAM_PCH_HEADERS} ${ARGN})
  endif()
endfunction()
