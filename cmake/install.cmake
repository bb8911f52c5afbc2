# cmake/install.cmake — `cmake --install` exports the libraries, their headers, the ncosim
# executable and a CMake package: find_package(ncosim) gives ncosim::core (the whole simulator:
# scenario reader, campaign, outputs, CLI and every built-in kind) and the layers below it
# (ncosim::kernel, ncosim::config, ncosim::models, ncosim::lmi, ncosim::estimators, ncosim::network,
# ncosim::sumo
# when built with SUMO, and sim/'s sub-layers ncosim::sim_files, ncosim::sim_scenario,
# ncosim::sim_run, ncosim::sim_store, ncosim::sim_analysis and ncosim::sim_present). docs/extending.md shows a program built on it.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(NCOSIM_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/ncosim)
set(NCOSIM_EXPORTED ncosim_kernel ncosim_config ncosim_models ncosim_lmi ncosim_estimators
    ncosim_network ncosim_sim_files ncosim_sim_scenario ncosim_sim_run ncosim_sim_store ncosim_sim_analysis
    ncosim_sim_present ncosim_core)
if(NCOSIM_SUMO)
  list(APPEND NCOSIM_EXPORTED ncosim_sumo)
endif()
foreach(t IN LISTS NCOSIM_EXPORTED)
  string(REPLACE "ncosim_" "" short ${t})
  set_target_properties(${t} PROPERTIES EXPORT_NAME ${short})
  add_library(ncosim::${short} ALIAS ${t})
  # Headers are installed under include/ncosim, keeping the in-tree paths ("sim/scenario/scenario.h").
  target_include_directories(${t} INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}/ncosim>)
endforeach()

install(TARGETS ${NCOSIM_EXPORTED} EXPORT ncosim-targets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS ncosim RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
if(NCOSIM_SUMO)
  # The live-SUMO module is opened by path (NCOSIM_SUMO_MODULE_PATH, the build tree's copy).
  install(TARGETS ncosim_sumo_session LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/ncosim)
endif()
foreach(dir kernel config sim models estimators lmi network sumo)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/ncosim/${dir}
          FILES_MATCHING PATTERN "*.h"
          PATTERN "ns3" EXCLUDE)  # the ns-3 backend's own headers (network/ns3/) are private
endforeach()

install(EXPORT ncosim-targets NAMESPACE ncosim:: DESTINATION ${NCOSIM_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/ncosimConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/ncosimConfig.cmake
                              INSTALL_DESTINATION ${NCOSIM_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/ncosimConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/ncosimConfig.cmake ${PROJECT_BINARY_DIR}/ncosimConfigVersion.cmake
        DESTINATION ${NCOSIM_INSTALL_CMAKEDIR})
