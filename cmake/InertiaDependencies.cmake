# Every dependency is a Debian 12 package; inertia.sh installs them (list in cmake/debian-packages.txt).
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(tomlplusplus 3.3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(fmt REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(spectra 1.0 REQUIRED)         # header-only: leading eigenvalues by Lanczos (diagnose)
find_package(Boost 1.74 REQUIRED)          # header-only parts: Math (Student's t), Lockfree (benchmark peer)
find_package(Threads REQUIRED)
# OpenMP (GCC's libgomp, which comes with the compiler): the analyzer's per-column loops run on
# --jobs threads (common/parallel.hpp). Optional: without it (clang lacking libomp, as the fuzz
# build) the loops run serially. Eigen's own products stay single-threaded in every file
# (EIGEN_DONT_PARALLELIZE): a product split over threads would sum in another order with another
# thread count, and Eigen inlines differently in files with and without OpenMP.
find_package(OpenMP COMPONENTS CXX)
add_compile_definitions(EIGEN_DONT_PARALLELIZE)
find_package(OpenSSL 3 REQUIRED COMPONENTS Crypto)   # libcrypto: HMAC-SHA256 of signed operator requests, the record's SHA-256
find_package(SQLite3 REQUIRED)                       # libsqlite3: the lab's record of characterizations
find_package(GTest REQUIRED)
find_package(benchmark REQUIRED)
find_package(Java 17 COMPONENTS Development REQUIRED)
include(UseJava)
find_package(PkgConfig REQUIRED)
pkg_check_modules(GPIODCXX REQUIRED IMPORTED_TARGET libgpiodcxx)
pkg_check_modules(MODBUS REQUIRED IMPORTED_TARGET libmodbus)
pkg_check_modules(PQ REQUIRED IMPORTED_TARGET libpq)          # libpq: the lab's record on a shared PostgreSQL server
pkg_check_modules(SYSTEMD REQUIRED IMPORTED_TARGET libsystemd)
pkg_check_modules(FFTW3 REQUIRED IMPORTED_TARGET fftw3)       # libfftw3: the analyzer's Fourier transforms (analyzer/noise/fourier.hpp)

# lcm.pc requires glib although the headers do not; locate the library directly.
find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp REQUIRED)
find_library(LCM_LIBRARY lcm REQUIRED)
find_program(LCM_GEN lcm-gen REQUIRED)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java REQUIRED)
add_library(lcm::lcm UNKNOWN IMPORTED)
set_target_properties(lcm::lcm PROPERTIES IMPORTED_LOCATION ${LCM_LIBRARY}
                                          INTERFACE_INCLUDE_DIRECTORIES ${LCM_INCLUDE_DIR})
