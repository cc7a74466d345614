# Included by the top-level CMakeLists.txt: the library users link (docs/package.md). The layer libraries
# stay the build's own; mktree_static (libmktree.a, exported as mktree::mktree) and mktree_shared
# (libmktree.so, mktree::mktree_shared) are made of their object files, compiled once. viz and the command
# line are not part of it. Usage requirements: the public headers (include/ and the generated version.h)
# and, for the archive, the libraries its objects need (mktreeConfig.cmake finds them again).
include(GNUInstallDirs)

set(MKTREE_PACKAGE_LAYERS mktree_storage mktree_core mktree_geometry mktree_scene mktree_generator
  mktree_tree mktree_store_format mktree_shard mktree_revision mktree_ingest mktree_clash mktree_query
  mktree_changes mktree_coordination)
set(MKTREE_PACKAGE_DEPENDENCIES hdf5::hdf5 PkgConfig::ZSTD PkgConfig::XXHASH assimp::assimp Threads::Threads)
if(NOT TARGET hdf5::hdf5)
  message(FATAL_ERROR "FindHDF5 made no hdf5::hdf5 target (CMake ${CMAKE_VERSION})")
endif()

set(_mktree_objects "")
foreach(layer IN LISTS MKTREE_PACKAGE_LAYERS)
  get_target_property(_type ${layer} TYPE)
  if(_type STREQUAL "STATIC_LIBRARY")
    list(APPEND _mktree_objects $<TARGET_OBJECTS:${layer}>)
  endif()
endforeach()

add_library(mktree_static STATIC ${_mktree_objects})
add_library(mktree::mktree ALIAS mktree_static)
set_target_properties(mktree_static PROPERTIES OUTPUT_NAME mktree EXPORT_NAME mktree)
set(MKTREE_PACKAGE_TARGETS mktree_static)
if(MKTREE_BUILD_SHARED)
  add_library(mktree_shared SHARED ${_mktree_objects})
  add_library(mktree::mktree_shared ALIAS mktree_shared)
  # Before 1.0 a minor version may change the ABI.
  set_target_properties(mktree_shared PROPERTIES OUTPUT_NAME mktree EXPORT_NAME mktree_shared
    VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
  if(NOT MKTREE_SANITIZE AND NOT MKTREE_BUILD_FUZZERS)
    # Every symbol resolved at link time: the shared object names all it needs (not so under sanitizers,
    # whose runtime only the executable links).
    target_link_options(mktree_shared PRIVATE -Wl,--no-undefined)
  endif()
  list(APPEND MKTREE_PACKAGE_TARGETS mktree_shared)
endif()
foreach(target IN LISTS MKTREE_PACKAGE_TARGETS)
  set_target_properties(${target} PROPERTIES LINKER_LANGUAGE CXX)
  target_compile_features(${target} PUBLIC cxx_std_20)
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include> $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(${target} PRIVATE ${MKTREE_PACKAGE_DEPENDENCIES})
endforeach()
