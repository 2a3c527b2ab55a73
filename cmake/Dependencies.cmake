# Every dependency is a Debian 12 package (scripts/install-deps.sh installs them).
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)
find_package(SQLite3 REQUIRED)
find_package(PostgreSQL REQUIRED)  # libpq: the store's PostgreSQL backend (daemon/store/pg_db.h)
find_package(nlohmann_json 3 REQUIRED)
find_package(spdlog REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(GTest REQUIRED)
find_package(benchmark REQUIRED)
find_package(PNG REQUIRED)
find_package(ZLIB REQUIRED)
# Boost.Beast (header-only in Boost 1.74) parses HTTP for meshmarkd's API.
find_package(Boost 1.74 REQUIRED)

pkg_check_modules(SODIUM REQUIRED IMPORTED_TARGET libsodium)
# lib3mf 1.x (3MF reading and writing), its C interface. Not through its pkg-config file, which
# names -lzip although the shared library already links it (and libzip-dev is not needed).
find_path(LIB3MF_INCLUDE_DIR Model/COM/NMR_DLLInterfaces.h PATH_SUFFIXES lib3mf REQUIRED)
find_library(LIB3MF_LIB 3MF REQUIRED)
# tinygltf (compiled, Debian's libtinygltf-dev) and libdraco for glTF/GLB and their Draco meshes.
find_package(TinyGLTF REQUIRED)
find_package(draco REQUIRED)
add_library(mm_lib3mf INTERFACE)
target_include_directories(mm_lib3mf SYSTEM INTERFACE ${LIB3MF_INCLUDE_DIR})
target_link_libraries(mm_lib3mf INTERFACE ${LIB3MF_LIB})

# OpenMesh: Debian ships headers and libs without a usable CMake config.
find_path(OPENMESH_INCLUDE_DIR OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh REQUIRED)
find_library(OPENMESH_CORE_LIB OpenMeshCore REQUIRED)
find_library(OPENMESH_TOOLS_LIB OpenMeshTools REQUIRED)
add_library(mm_openmesh INTERFACE)
target_include_directories(mm_openmesh SYSTEM INTERFACE ${OPENMESH_INCLUDE_DIR})
target_link_libraries(mm_openmesh INTERFACE ${OPENMESH_TOOLS_LIB} ${OPENMESH_CORE_LIB})
target_compile_definitions(mm_openmesh INTERFACE _USE_MATH_DEFINES)

# OpenSubdiv: Debian's CMake config is broken; link osdCPU and use <opensubdiv/far/...>.
find_path(OSD_INCLUDE_DIR opensubdiv/far/topologyRefiner.h REQUIRED)
find_library(OSD_CPU_LIB osdCPU REQUIRED)
add_library(mm_opensubdiv INTERFACE)
target_include_directories(mm_opensubdiv SYSTEM INTERFACE ${OSD_INCLUDE_DIR})
target_link_libraries(mm_opensubdiv INTERFACE ${OSD_CPU_LIB})

# Spectra (header-only) for partial eigen-decompositions of large meshes.
find_path(SPECTRA_INCLUDE_DIR Spectra/SymEigsSolver.h REQUIRED)
add_library(mm_spectra INTERFACE)
target_include_directories(mm_spectra SYSTEM INTERFACE ${SPECTRA_INCLUDE_DIR})
target_link_libraries(mm_spectra INTERFACE Eigen3::Eigen)

# CGAL 5.5 is header-only; used for AABB-tree distances.
find_package(CGAL REQUIRED)

# OpenCASCADE 7.6 (STEP and IGES parts): its toolkits by name; the include folder is opencascade/.
find_path(OCCT_INCLUDE_DIR STEPControl_Reader.hxx PATH_SUFFIXES opencascade REQUIRED)
add_library(mm_occt INTERFACE)
target_include_directories(mm_occt SYSTEM INTERFACE ${OCCT_INCLUDE_DIR})
foreach(tk TKSTEP TKSTEPAttr TKSTEPBase TKSTEP209 TKIGES TKXSBase TKMesh TKBO TKPrim TKShHealing TKTopAlgo
           TKGeomAlgo TKBRep TKGeomBase TKG3d TKG2d TKMath TKernel)
  find_library(OCCT_${tk}_LIB ${tk} REQUIRED)
  target_link_libraries(mm_occt INTERFACE ${OCCT_${tk}_LIB})
endforeach()
