# The Debian package `locus`, made in the build directory with
#   cpack -G DEB            (docs/deploy.md "Bare metal with systemd")
# It holds the three binaries (/usr/bin), their manual pages (from --help by
# help2man), the systemd units locus-coordinator.service and
# locus-worker@.service (deploy/systemd/), and their flags in
# /etc/locus/coordinator.conf and worker.conf (conffiles). postinst makes
# the system user `locus` and /var/lib/locus. The dependencies are the
# packages of the shared libraries the binaries load (dpkg-shlibdeps).
# tests/package/run.sh installs it into a fresh Debian 12 root.
if(NOT (TARGET locus AND TARGET locus-coordinator AND TARGET locus-worker))
  return()
endif()

# The package's version: raise it for each release that is installed over
# an older one (apt upgrades only to a higher version).
set(LOCUS_PACKAGE_VERSION 0.1.0)
set(LOCUS_PACKAGE_MAINTAINER "Locus maintainers <maintainers@locus.invalid>" CACHE STRING
  "Maintainer field of the Debian package")
set(locus_debian ${CMAKE_CURRENT_LIST_DIR})
set(locus_systemd ${CMAKE_SOURCE_DIR}/deploy/systemd)

install(TARGETS locus locus-coordinator locus-worker RUNTIME DESTINATION bin)
# The image plugin (common/base/image_plugin.h): a private library, where
# the binaries look for it, bin/../lib/locus (/usr/lib/locus).
install(TARGETS locus-image-io LIBRARY DESTINATION lib/locus)
# lib/systemd/system under the prefix /usr: /usr/lib/systemd/system, which
# is /lib/systemd/system on Debian 12's merged /usr.
install(FILES ${locus_systemd}/locus-coordinator.service ${locus_systemd}/locus-worker@.service
  DESTINATION lib/systemd/system)
install(FILES ${locus_systemd}/coordinator.conf ${locus_systemd}/worker.conf DESTINATION /etc/locus)

# Manual pages, made with the binaries (the build runs them for --help).
find_program(LOCUS_HELP2MAN help2man)
if(LOCUS_HELP2MAN)
  set(pages)
  foreach(program locus locus-coordinator locus-worker)
    set(page ${CMAKE_BINARY_DIR}/man/${program}.1.gz)
    add_custom_command(OUTPUT ${page}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/man
      COMMAND ${locus_debian}/make-man.sh $<TARGET_FILE_DIR:${program}> ${program}
              ${LOCUS_PACKAGE_VERSION} ${page}
      DEPENDS ${program} ${locus_debian}/make-man.sh
      COMMENT "Manual page of ${program} (help2man)" VERBATIM)
    list(APPEND pages ${page})
  endforeach()
  add_custom_target(locus_man ALL DEPENDS ${pages})
  install(FILES ${pages} DESTINATION share/man/man1)
else()
  message(STATUS "help2man not found: the Debian package will have no manual pages "
                 "(deploy/local/install-deps.sh installs it)")
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME locus)
set(CPACK_PACKAGE_VERSION ${LOCUS_PACKAGE_VERSION})
set(CPACK_PACKAGE_CONTACT ${LOCUS_PACKAGE_MAINTAINER})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "distributed renderer: scanline rendering with local ray tracing")
# The long description (CPack puts the summary above it and indents it).
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
  "Locus renders scenes with Nakamae, Tadamura and Nishita's local ray tracing
(a scanline renderer that ray traces only where mirrors and glass need it)
or a Whitted ray tracer, alone or on a render farm: a coordinator splits
frames into bands that workers render, frames identical to a
single-process render.

This package has the CLI (locus), the coordinator (locus-coordinator) and
the worker (locus-worker), with systemd units for the coordinator and for
one worker per core (locus-worker@N), configured in /etc/locus.")
set(CPACK_DEBIAN_PACKAGE_SECTION graphics)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# Beyond the libraries: postinst's groupadd and useradd (not Essential).
set(CPACK_DEBIAN_PACKAGE_DEPENDS "passwd")
# Movies (--movie) run Debian's ffmpeg; without it only they fail.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "ffmpeg")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
  ${locus_debian}/conffiles ${locus_debian}/postinst ${locus_debian}/prerm ${locus_debian}/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_STRIP_FILES ON)
# The package only: no source package of the tree (it would take build/).
set(CPACK_SOURCE_GENERATOR "")
include(CPack)
