# Cross-compile rdslam for 64-bit ARM (Raspberry Pi 4/5, Jetson) with Debian's
# aarch64-linux-gnu-g++ against an arm64 Debian 12 sysroot made by
# toolchain/make-arm64-sysroot.sh. Tests run under qemu-aarch64 through
# CMAKE_CROSSCOMPILING_EMULATOR, so `ctest` works unchanged.
#
#   cmake -S . -B build-aarch64/build -DCMAKE_TOOLCHAIN_FILE=toolchain/aarch64-linux-gnu.cmake \
#         -DRDSLAM_SYSROOT=$PWD/build-aarch64/sysroot
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

# try_compile projects see the variable through CMAKE_TRY_COMPILE_PLATFORM_VARIABLES.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES RDSLAM_SYSROOT)
if(NOT RDSLAM_SYSROOT AND DEFINED ENV{RDSLAM_SYSROOT})
  set(RDSLAM_SYSROOT "$ENV{RDSLAM_SYSROOT}")
endif()
if(NOT RDSLAM_SYSROOT)
  set(RDSLAM_SYSROOT "${CMAKE_CURRENT_LIST_DIR}/../build-aarch64/sysroot")
endif()
get_filename_component(RDSLAM_SYSROOT "${RDSLAM_SYSROOT}" ABSOLUTE)
if(NOT EXISTS "${RDSLAM_SYSROOT}/usr/include")
  message(FATAL_ERROR "aarch64 sysroot not found at ${RDSLAM_SYSROOT}: "
                      "run toolchain/make-arm64-sysroot.sh first")
endif()

set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_SYSROOT "${RDSLAM_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${RDSLAM_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)  # lcm-gen, pkg-config: the host's
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

# The sysroot's shared libraries are found at link time through -rpath-link.
set(_rdslam_libdirs "${RDSLAM_SYSROOT}/usr/lib/aarch64-linux-gnu;${RDSLAM_SYSROOT}/lib/aarch64-linux-gnu")
foreach(_d ${_rdslam_libdirs})
  string(APPEND CMAKE_EXE_LINKER_FLAGS_INIT " -Wl,-rpath-link,${_d}")
  string(APPEND CMAKE_SHARED_LINKER_FLAGS_INIT " -Wl,-rpath-link,${_d}")
endforeach()
# BLAS/LAPACK alternatives live in subfolders in Debian.
foreach(_d blas lapack openblas-pthread)
  if(EXISTS "${RDSLAM_SYSROOT}/usr/lib/aarch64-linux-gnu/${_d}")
    string(APPEND CMAKE_EXE_LINKER_FLAGS_INIT
           " -Wl,-rpath-link,${RDSLAM_SYSROOT}/usr/lib/aarch64-linux-gnu/${_d}")
  endif()
endforeach()

set(ENV{PKG_CONFIG_SYSROOT_DIR} "${RDSLAM_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
    "${RDSLAM_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${RDSLAM_SYSROOT}/usr/share/pkgconfig:${RDSLAM_SYSROOT}/usr/lib/pkgconfig")

find_program(RDSLAM_QEMU qemu-aarch64)
if(RDSLAM_QEMU)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${RDSLAM_QEMU};-L;${RDSLAM_SYSROOT}")
endif()
