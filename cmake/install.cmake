# Included by the top-level CMakeLists.txt when MKTREE_INSTALL is on (docs/package.md): the libraries, the
# public headers of include/mktree/ and the generated version.h, the mktree command line, the CMake package
# (mktreeConfig.cmake, its version file, the exported targets), mktree.pc and the LICENSE.
include(CMakePackageConfigHelpers)
foreach(dir CMAKE_INSTALL_LIBDIR CMAKE_INSTALL_INCLUDEDIR)
  if(IS_ABSOLUTE "${${dir}}")
    message(FATAL_ERROR "${dir}=${${dir}}: the mktree package is relocatable and needs a path relative to the prefix")
  endif()
endforeach()
set(MKTREE_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/mktree)

install(TARGETS ${MKTREE_PACKAGE_TARGETS} EXPORT mktreeTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The STEP reader's module (engine/scene/step_reader.h), found beside the libraries at run time.
install(TARGETS mktree_step LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/mktree)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/mktree DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
  FILES_MATCHING PATTERN "*.h")
install(FILES ${PROJECT_BINARY_DIR}/include/mktree/version.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/mktree)
if(MKTREE_BUILD_TOOLS)
  install(TARGETS mktree RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()

install(EXPORT mktreeTargets NAMESPACE mktree:: FILE mktreeTargets.cmake DESTINATION ${MKTREE_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/mktreeConfig.cmake.in
  ${PROJECT_BINARY_DIR}/package/mktreeConfig.cmake INSTALL_DESTINATION ${MKTREE_INSTALL_CMAKEDIR})
# 0.x: a 0.y release satisfies find_package(mktree 0.x) for any x <= y.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/package/mktreeConfigVersion.cmake
  COMPATIBILITY SameMajorVersion)
install(FILES ${PROJECT_BINARY_DIR}/package/mktreeConfig.cmake ${PROJECT_BINARY_DIR}/package/mktreeConfigVersion.cmake
  DESTINATION ${MKTREE_INSTALL_CMAKEDIR})

# mktree.pc finds the prefix from its own place (${pcfiledir}), so it is right for any --prefix.
file(RELATIVE_PATH MKTREE_PC_TO_PREFIX /${CMAKE_INSTALL_LIBDIR}/pkgconfig /)
string(REGEX REPLACE "/$" "" MKTREE_PC_TO_PREFIX "${MKTREE_PC_TO_PREFIX}")
configure_file(${PROJECT_SOURCE_DIR}/cmake/mktree.pc.in ${PROJECT_BINARY_DIR}/package/mktree.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/package/mktree.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

install(FILES ${PROJECT_SOURCE_DIR}/LICENSE DESTINATION ${CMAKE_INSTALL_DOCDIR})
