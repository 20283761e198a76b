# find_package(spatial_dynamics_c) for CMake projects (an ament_cmake controller package, say).
# Defines two imported targets over the C ABI (headers spatial_dynamics.h and .hpp):
#   spatial_dynamics_c::spatial_dynamics_c   the shared library libspatial_dynamics_c.so
#   spatial_dynamics_c::static               the static library libspatial_dynamics_c.a (with
#                                            the threads, dl and m libraries it needs)
# and spatial_dynamics_c_INCLUDE_DIR, spatial_dynamics_c_LIBRARY, spatial_dynamics_c_STATIC_LIBRARY.
#
# Found from either layout of this file:
#   the repository: src/c/cmake/ here, headers in src/c/include/, libraries in target/release/
#     (`cargo build --release -p spatial_dynamics_c`; or in $CARGO_TARGET_DIR/release/);
#   an install: <prefix>/lib/cmake/spatial_dynamics_c/ here, <prefix>/include/, <prefix>/lib/.
# SPATIAL_DYNAMICS_C_LIBRARY_DIR (a CMake or environment variable) names another library folder.
include(CMakeFindDependencyMacro)
find_dependency(Threads)

get_filename_component(_sd_here "${CMAKE_CURRENT_LIST_DIR}" REALPATH)
set(_sd_library_dirs
    ${SPATIAL_DYNAMICS_C_LIBRARY_DIR} $ENV{SPATIAL_DYNAMICS_C_LIBRARY_DIR}
    "${_sd_here}/../../../target/release" "$ENV{CARGO_TARGET_DIR}/release" "${_sd_here}/../..")

find_path(spatial_dynamics_c_INCLUDE_DIR spatial_dynamics.h
          HINTS "${_sd_here}/../include" "${_sd_here}/../../../include" NO_DEFAULT_PATH)
find_library(spatial_dynamics_c_LIBRARY NAMES libspatial_dynamics_c.so spatial_dynamics_c
             HINTS ${_sd_library_dirs} NO_DEFAULT_PATH)
find_library(spatial_dynamics_c_STATIC_LIBRARY NAMES libspatial_dynamics_c.a
             HINTS ${_sd_library_dirs} NO_DEFAULT_PATH)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(spatial_dynamics_c
  REQUIRED_VARS spatial_dynamics_c_LIBRARY spatial_dynamics_c_INCLUDE_DIR
  REASON_FAILURE_MESSAGE "build it with `cargo build --release -p spatial_dynamics_c`, or set SPATIAL_DYNAMICS_C_LIBRARY_DIR")

if(spatial_dynamics_c_FOUND AND NOT TARGET spatial_dynamics_c::spatial_dynamics_c)
  add_library(spatial_dynamics_c::spatial_dynamics_c SHARED IMPORTED)
  # Cargo gives the library no SONAME: link it by name, found at run time through the RPATH.
  set_target_properties(spatial_dynamics_c::spatial_dynamics_c PROPERTIES
    IMPORTED_LOCATION "${spatial_dynamics_c_LIBRARY}"
    IMPORTED_NO_SONAME TRUE
    INTERFACE_INCLUDE_DIRECTORIES "${spatial_dynamics_c_INCLUDE_DIR}")
endif()
if(spatial_dynamics_c_STATIC_LIBRARY AND NOT TARGET spatial_dynamics_c::static)
  add_library(spatial_dynamics_c::static STATIC IMPORTED)
  set_target_properties(spatial_dynamics_c::static PROPERTIES
    IMPORTED_LOCATION "${spatial_dynamics_c_STATIC_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${spatial_dynamics_c_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "Threads::Threads;${CMAKE_DL_LIBS};m")
endif()
unset(_sd_here)
unset(_sd_library_dirs)
