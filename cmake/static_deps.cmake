# The C libraries roe reads files with (zlib, bzip2, LZ4, Zstandard, SQLite, yaml-cpp, OpenSSL's libcrypto),
# linked from their static archives where the -dev packages ship them (Debian's do).
#
# Why (issue 53 item 4, docs/BENCHMARKS.md "Start-up"): a short command's CPU time is mostly the dynamic
# loader's. `roe --version` executed 11.3 M instructions with these libraries shared, 5.9 M with them static
# (callgrind, 2026-12-07); libcrypto alone cost 2.5 M at load, for the one SHA-256 roe uses. Linked
# statically, the linker keeps only the objects roe calls and resolves their symbols once, at link time.
# libstdc++ and fmt stay shared (fmt's package has no archive, and fmt needs libstdc++).
#
# -DROE_STATIC_DEPS=OFF links the shared libraries instead (a distribution package would choose that).
option(ROE_STATIC_DEPS "link roe's file-format C libraries from their static archives where they exist" ON)

# Sets `out` to a static imported target for `archive` (a file name such as libz.a) when ROE_STATIC_DEPS is
# on and the archive is found, carrying `shared`'s include directories and the extra link libraries given
# after the archive's name; otherwise to `shared`.
function(roe_prefer_static out shared archive)
  set(${out} ${shared} PARENT_SCOPE)
  if(NOT ROE_STATIC_DEPS)
    return()
  endif()
  string(MAKE_C_IDENTIFIER "${archive}" id)
  find_library(ROE_STATIC_${id} NAMES ${archive})
  if(NOT ROE_STATIC_${id})
    return()
  endif()
  set(t roe_static_${id})
  add_library(${t} STATIC IMPORTED)
  set_target_properties(${t} PROPERTIES IMPORTED_LOCATION ${ROE_STATIC_${id}})
  get_target_property(inc ${shared} INTERFACE_INCLUDE_DIRECTORIES)
  if(inc)
    set_target_properties(${t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${inc}")
  endif()
  if(ARGN)
    set_target_properties(${t} PROPERTIES INTERFACE_LINK_LIBRARIES "${ARGN}")
  endif()
  set(${out} ${t} PARENT_SCOPE)
endfunction()

find_package(Threads REQUIRED)
roe_prefer_static(ROE_DEP_ZLIB ZLIB::ZLIB libz.a)
roe_prefer_static(ROE_DEP_BZIP2 BZip2::BZip2 libbz2.a)
roe_prefer_static(ROE_DEP_LZ4 PkgConfig::LZ4 liblz4.a)
roe_prefer_static(ROE_DEP_ZSTD PkgConfig::ZSTD libzstd.a Threads::Threads)
roe_prefer_static(ROE_DEP_SQLITE SQLite::SQLite3 libsqlite3.a Threads::Threads ${CMAKE_DL_LIBS} m)
roe_prefer_static(ROE_DEP_YAML yaml-cpp libyaml-cpp.a)
roe_prefer_static(ROE_DEP_CRYPTO OpenSSL::Crypto libcrypto.a Threads::Threads ${CMAKE_DL_LIBS})
