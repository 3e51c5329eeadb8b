# Install rules so that another project can `find_package(viscd)` and link `viscd::viscd`, and
# `find_package(viscd COMPONENTS tools)` for `viscd::tools` as well. Each library has an export
# set (and targets file) of its own; viscdConfig.cmake loads the tools file only when asked.
include(CMakePackageConfigHelpers)

install(TARGETS viscd EXPORT viscdTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS viscd_tools EXPORT viscdToolsTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# One include folder for both: io.hpp and scene.hpp are installed with the rest and usable once
# viscd::tools is linked.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/viscd DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${PROJECT_SOURCE_DIR}/LICENSE DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/viscd)
install(EXPORT viscdTargets NAMESPACE viscd:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
install(EXPORT viscdToolsTargets NAMESPACE viscd:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)

# The adapters (docs/adapters.md), each in an export set of its own, installed when built:
# find_package(viscd COMPONENTS bullet) for viscd::bullet, COMPONENTS fcl for viscd::fcl.
# viscd::bullet names the Bullet libraries and include folder found at build time (Bullet's
# package gives no imported targets); viscd::fcl names FCL's target, which viscdConfig finds.
if(TARGET viscd_bullet)
  install(TARGETS viscd_bullet EXPORT viscdBulletTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT viscdBulletTargets NAMESPACE viscd:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
endif()
if(TARGET viscd_fcl)
  install(TARGETS viscd_fcl EXPORT viscdFclTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT viscdFclTargets NAMESPACE viscd:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
endif()

# The distributed detector (docs/mpi.md): find_package(viscd COMPONENTS mpi) for viscd::mpi, which
# names MPI's C target (viscdConfig finds MPI for it).
if(TARGET viscd_mpi)
  install(TARGETS viscd_mpi EXPORT viscdMpiTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT viscdMpiTargets NAMESPACE viscd:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
endif()

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/viscdConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/viscdConfig.cmake
                              INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/viscdConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/viscdConfig.cmake ${PROJECT_BINARY_DIR}/viscdConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/viscd)
if(TARGET viscd_app)
  install(TARGETS viscd_app RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
# `viscd bench` finds its plot scripts in <prefix>/share/viscd and the peers driver in
# <prefix>/libexec/viscd when installed.
if(TARGET viscd_app)
  install(FILES ${PROJECT_SOURCE_DIR}/bench/plot_paper.py ${PROJECT_SOURCE_DIR}/bench/plot_peers.py
          DESTINATION ${CMAKE_INSTALL_DATADIR}/viscd)
endif()
if(TARGET viscd_peers)
  install(TARGETS viscd_peers RUNTIME DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/viscd)
endif()
