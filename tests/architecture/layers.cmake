# cmake -D ROOT=<repository> -P tests/architecture/layers.cmake
# The layers of docs/architecture.md, enforced: every `#include "..."` of a source folder must name a header
# of the folder itself or of a folder below it; the public headers include only <mktree/...>, so they build
# from an install with nothing but include/ on the include path. Checked: include/, storage/, engine/,
# tools/ (and tools/mpi/), python/ and bench/, every subfolder a layer of its own that must be placed here.
# Prints every violation; fails if any.
cmake_minimum_required(VERSION 3.20)
if(NOT ROOT)
  message(FATAL_ERROR "usage: cmake -D ROOT=<repository> -P layers.cmake")
endif()

# folder -> the include prefixes it may use (besides its own files). A prefix covers its subfolders; a
# folder's own prefix covers only the files directly in it, so a subfolder is a layer of its own.
set(below_include_mktree "mktree/")
set(below_storage "mktree/")
set(below_engine_core "mktree/")
set(below_engine_geometry "mktree/" "engine/core/")
set(below_engine_scene "mktree/" "storage/" "engine/core/")
# The STEP reader's OpenCASCADE module (libmktree_step.so), loaded by engine/scene/step_reader.cc.
set(below_engine_step "mktree/" "storage/" "engine/core/" "engine/scene/")
set(below_engine_generator "mktree/" "storage/" "engine/core/" "engine/scene/")
set(below_engine_tree "mktree/" "storage/" "engine/core/")
set(below_engine_store_format "mktree/" "storage/" "engine/core/" "engine/tree/")
set(below_engine_shard "mktree/" "storage/" "engine/core/")
set(below_engine_ingest "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/scene/" "engine/generator/"
    "engine/tree/" "engine/store_format/" "engine/shard/")
set(below_engine_revision "mktree/" "storage/" "engine/core/" "engine/shard/")
set(below_engine_clash "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/tree/" "engine/store_format/")
set(below_engine_query "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/tree/" "engine/store_format/"
    "engine/clash/" "engine/shard/" "engine/revision/")
# The changes a store takes: its writer builds delta and base stores (ingest) and reads revisions (query).
set(below_engine_changes "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/scene/" "engine/tree/"
    "engine/store_format/" "engine/shard/" "engine/ingest/" "engine/clash/" "engine/query/" "engine/revision/")
set(below_engine_viz "mktree/" "storage/" "engine/core/" "engine/tree/" "engine/store_format/")
# The clash workflow: tests of one selection against another, rules, keys, groups, comparison with a
# previous run (over the query layer's Database and its clash).
set(below_engine_coordination "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/tree/"
    "engine/store_format/" "engine/clash/" "engine/shard/" "engine/revision/" "engine/query/")
# What the workflow hands to people and their tools: BCF archives, the HTML report, snapshots (viz).
set(below_engine_report "mktree/" "storage/" "engine/core/" "engine/geometry/" "engine/tree/"
    "engine/store_format/" "engine/clash/" "engine/shard/" "engine/revision/" "engine/query/"
    "engine/coordination/" "engine/viz/")
set(below_tools "mktree/" "storage/" "engine/")
# The MPI front end (mktree-mpi) is a sibling of the command line above the engine: it may share the
# command line's helpers, never the reverse.
set(below_tools_mpi "mktree/" "storage/" "engine/" "tools/")
# The Python module sees only the public API, as a user's program does.
set(below_python "mktree/")
# Benchmarks measure the engine's layers directly; nothing includes them.
set(below_bench "mktree/" "storage/" "engine/")
set(folders include/mktree storage engine/core engine/geometry engine/scene engine/step engine/generator engine/tree
    engine/store_format engine/shard engine/revision engine/ingest engine/clash engine/query engine/changes engine/viz
    engine/coordination engine/report tools tools/mpi python bench)

# Every folder that holds sources (at any depth) must be placed in the layers above before it can hold code.
set(roots include storage engine tools python bench)
set(all_sources "")
foreach(root IN LISTS roots)
  file(GLOB_RECURSE found RELATIVE ${ROOT} ${ROOT}/${root}/*.h ${ROOT}/${root}/*.cc)
  list(APPEND all_sources ${found})
endforeach()
foreach(src IN LISTS all_sources)
  get_filename_component(dir ${src} DIRECTORY)
  if(NOT dir IN_LIST folders)
    message(FATAL_ERROR "${src}: in ${dir}/, a folder the layers do not place (tests/architecture/layers.cmake)")
  endif()
endforeach()
# A folder of the engine with no sources yet must be placed too.
file(GLOB engine_dirs RELATIVE ${ROOT} LIST_DIRECTORIES true ${ROOT}/engine/*)
foreach(dir IN LISTS engine_dirs)
  if(IS_DIRECTORY ${ROOT}/${dir} AND NOT dir IN_LIST folders)
    message(FATAL_ERROR "${dir}: a folder the layers do not place (tests/architecture/layers.cmake)")
  endif()
endforeach()

set(violations 0)
set(checked 0)
foreach(folder IN LISTS folders)
  string(REPLACE "/" "_" key "${folder}")
  set(allowed ${below_${key}})
  if(folder STREQUAL "include/mktree")
    set(own "mktree")
  else()
    set(own "${folder}")
  endif()
  file(GLOB sources RELATIVE ${ROOT} ${ROOT}/${folder}/*.h ${ROOT}/${folder}/*.cc)
  foreach(src IN LISTS sources)
    math(EXPR checked "${checked} + 1")
    file(STRINGS ${ROOT}/${src} lines REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]")
    foreach(line IN LISTS lines)
      if(line MATCHES "#[ \t]*include[ \t]*\"([^\"]+)\"")
        set(inc "${CMAKE_MATCH_1}")
      elseif(line MATCHES "#[ \t]*include[ \t]*<(mktree/[^>]+|storage/[^>]+|engine/[^>]+|tools/[^>]+|bench/[^>]+|python/[^>]+)>")
        set(inc "${CMAKE_MATCH_1}")
      else()
        continue()  # a system or third-party header
      endif()
      get_filename_component(inc_dir "${inc}" DIRECTORY)
      set(ok FALSE)
      if(inc_dir STREQUAL own)
        set(ok TRUE)
      endif()
      foreach(prefix IN LISTS allowed)
        string(FIND "${inc}" "${prefix}" at)
        if(at EQUAL 0)
          set(ok TRUE)
          break()
        endif()
      endforeach()
      if(NOT ok)
        message("${src}: includes \"${inc}\", which is not in ${folder}/ or a layer below it")
        math(EXPR violations "${violations} + 1")
      endif()
    endforeach()
  endforeach()
endforeach()
if(checked LESS 50)
  message(FATAL_ERROR "layers.cmake: only ${checked} files found under ${ROOT}: wrong ROOT?")
endif()
if(violations GREATER 0)
  message(FATAL_ERROR "${violations} include(s) against the layers of docs/architecture.md")
endif()
message("layers: ${checked} files, every include goes down")
