# Installation into FHS places and the Debian package (issue 11). Included last from the
# top-level CMakeLists.txt.
#
#   cmake --install build                     # into CMAKE_INSTALL_PREFIX (default /usr)
#   cpack --config build/CPackConfig.cmake -G DEB -B out   # out/rdslam_<ver>_<arch>.deb
#
# With the default prefix /usr the layout is Debian's:
#   /usr/bin/rdslam                             the daemon and tools
#   /lib/systemd/system/rdslam.service          the unit (not enabled, not started)
#   /etc/rdslam/rdslam.yaml                     default configuration (a dpkg conffile)
#   /usr/lib/sysusers.d/rdslam.conf             the system user the unit runs as
#   /usr/share/rdslam/lcmtypes/*.lcm            message definitions for lcm-gen/lcm-spy
#   /usr/share/rdslam/python/rdslam_msgs.py     version-checked rdslam.pose_t decoding
#   /usr/share/rdslam/examples/                 optional drop-ins (real-time scheduling)
#   /usr/share/doc/rdslam/                      README and deployment notes
include(GNUInstallDirs)

# The project targets robots running Debian: install into /usr unless the user chose a
# prefix. (Set in the cache before GNUInstallDirs' FULL_* paths are used below.)
if(CMAKE_INSTALL_PREFIX_INITIALIZED_TO_DEFAULT)
  set(CMAKE_INSTALL_PREFIX "/usr" CACHE PATH "Install prefix" FORCE)
endif()
# GNUInstallDirs computed its FULL_* paths from the prefix at include time; recompute them
# for the (possibly changed) prefix. /usr maps sysconfdir to /etc (GNU coding standards).
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(RDSLAM_SYSCONFDIR "/etc")
  # Debian 12's systemd reads packaged units from /lib/systemd/system (pkg-config systemd
  # systemdsystemunitdir); /usr/lib/sysusers.d likewise.
  set(RDSLAM_UNITDIR_DEFAULT "/lib/systemd/system")
  set(RDSLAM_SYSUSERSDIR_DEFAULT "/usr/lib/sysusers.d")
else()
  set(RDSLAM_SYSCONFDIR "${CMAKE_INSTALL_PREFIX}/etc")
  set(RDSLAM_UNITDIR_DEFAULT "${CMAKE_INSTALL_PREFIX}/lib/systemd/system")
  set(RDSLAM_SYSUSERSDIR_DEFAULT "${CMAKE_INSTALL_PREFIX}/lib/sysusers.d")
endif()
# -DRDSLAM_SYSTEMD_UNIT_DIR=... / -DRDSLAM_SYSUSERS_DIR=... override; otherwise they follow
# the prefix on every configure (not cached, so a changed prefix is never half-applied).
if(NOT RDSLAM_SYSTEMD_UNIT_DIR)
  set(RDSLAM_SYSTEMD_UNIT_DIR "${RDSLAM_UNITDIR_DEFAULT}")
endif()
if(NOT RDSLAM_SYSUSERS_DIR)
  set(RDSLAM_SYSUSERS_DIR "${RDSLAM_SYSUSERSDIR_DEFAULT}")
endif()
set(RDSLAM_BINDIR "${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}")
set(RDSLAM_CONFIG_DIR "${RDSLAM_SYSCONFDIR}/rdslam")

# The unit in the repository names /usr/bin/rdslam and /etc/rdslam/rdslam.yaml (that file is
# what the tests verify); the installed copy names the configured paths.
file(READ ${CMAKE_SOURCE_DIR}/systemd/rdslam.service RDSLAM_UNIT_TEXT)
string(REPLACE "/usr/bin/rdslam" "${RDSLAM_BINDIR}/rdslam" RDSLAM_UNIT_TEXT "${RDSLAM_UNIT_TEXT}")
string(REPLACE "/etc/rdslam/" "${RDSLAM_CONFIG_DIR}/" RDSLAM_UNIT_TEXT "${RDSLAM_UNIT_TEXT}")
file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/packaging/rdslam.service CONTENT "${RDSLAM_UNIT_TEXT}"
     @ONLY)
set_property(DIRECTORY ${CMAKE_SOURCE_DIR} APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
             ${CMAKE_SOURCE_DIR}/systemd/rdslam.service)

install(TARGETS rdslam RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(FILES ${CMAKE_BINARY_DIR}/packaging/rdslam.service
        DESTINATION ${RDSLAM_SYSTEMD_UNIT_DIR})
install(FILES ${CMAKE_SOURCE_DIR}/systemd/rdslam.yaml DESTINATION ${RDSLAM_CONFIG_DIR})
install(FILES ${CMAKE_SOURCE_DIR}/systemd/rdslam.sysusers DESTINATION ${RDSLAM_SYSUSERS_DIR}
        RENAME rdslam.conf)
install(FILES ${CMAKE_SOURCE_DIR}/systemd/rdslam-realtime.conf
        DESTINATION ${CMAKE_INSTALL_DATADIR}/rdslam/examples)
install(FILES ${RDSLAM_LCM_FILES} DESTINATION ${CMAKE_INSTALL_DATADIR}/rdslam/lcmtypes)
install(FILES ${CMAKE_SOURCE_DIR}/tools/lcm/rdslam_msgs.py
        DESTINATION ${CMAKE_INSTALL_DATADIR}/rdslam/python)
# The place-recognition vocabulary (core/vocabulary.h): the source tree's copy while developing,
# the installed one otherwise (default_vocabulary_path()).
install(FILES ${CMAKE_SOURCE_DIR}/data/vocab/orb_k10l4.bin
        DESTINATION ${CMAKE_INSTALL_DATADIR}/rdslam/vocab)
set_source_files_properties(
  ${CMAKE_SOURCE_DIR}/core/vocabulary.cpp DIRECTORY ${CMAKE_SOURCE_DIR}/core
  PROPERTIES COMPILE_DEFINITIONS
  "RDSLAM_VOCAB_SOURCE=\"${CMAKE_SOURCE_DIR}/data/vocab/orb_k10l4.bin\";RDSLAM_VOCAB_INSTALLED=\"${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DATADIR}/rdslam/vocab/orb_k10l4.bin\"")
install(FILES ${CMAKE_SOURCE_DIR}/README.md ${CMAKE_SOURCE_DIR}/docs/deploy.md
        DESTINATION ${CMAKE_INSTALL_DOCDIR})

# ---- Debian package ----
set(CPACK_PACKAGE_NAME "rdslam")
set(CPACK_PACKAGE_VENDOR "rdslam")
set(CPACK_PACKAGE_CONTACT "rdslam maintainers <rdslam@localhost>")
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "monocular visual SLAM for dynamic environments, as a systemd service")
string(CONCAT CPACK_PACKAGE_DESCRIPTION
       "rdslam estimates a camera's 6-DoF pose and a sparse map from one camera (RDSLAM,\n"
       "Tan et al., ISMAR 2013) and publishes poses over LCM. The package installs the\n"
       "rdslam.service unit but neither enables nor starts it.")
set(CPACK_PACKAGING_INSTALL_PREFIX "${CMAKE_INSTALL_PREFIX}")
set(CPACK_STRIP_FILES ON)
set(CPACK_GENERATOR "DEB")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION "science")
set(CPACK_DEBIAN_PACKAGE_PRIORITY "optional")
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://example.invalid/rdslam")
# Runtime library dependencies are computed from the binary by dpkg-shlibdeps (so they
# always match what was linked: OpenCV, Ceres, LCM, yaml-cpp, libsystemd, turbojpeg, ...).
# The postinst needs systemd-sysusers or, without systemd, useradd from passwd.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd | passwd")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${CMAKE_SOURCE_DIR}/systemd/debian/conffiles ${CMAKE_SOURCE_DIR}/systemd/debian/postinst
    ${CMAKE_SOURCE_DIR}/systemd/debian/prerm ${CMAKE_SOURCE_DIR}/systemd/debian/postrm)
if(NOT CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  message(WARNING "rdslam: CMAKE_INSTALL_PREFIX is ${CMAKE_INSTALL_PREFIX}; the .deb's "
                  "maintainer scripts and conffiles assume /usr and /etc")
endif()
include(CPack)
