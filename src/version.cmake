# Writes pdsim_version.hpp with the git description of the source tree. Run at every build by the
# pdsim_version target, so that the provenance in output files names the commit actually built;
# configure_file rewrites the header only when the description changes (no needless rebuilds).
# usage: cmake -DSOURCE_DIR=... -DBINARY_DIR=... -DPROJECT_VERSION=... -P src/version.cmake
execute_process(COMMAND git describe --always --dirty --tags WORKING_DIRECTORY ${SOURCE_DIR}
                OUTPUT_VARIABLE PDSIM_GIT OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
configure_file(${SOURCE_DIR}/src/version.hpp.in ${BINARY_DIR}/pdsim_version.hpp @ONLY)
