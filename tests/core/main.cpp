// Core tier: the solver's YADE-independent parts (pkg/cd/core) checked without running YADE,
// against exact solutions and against the engine's own results. Built by the top-level CMake as
// `cd_core_tests`; run by tests/engine/test_core.py (so by the README's test command):
//
//   build/cd_core_tests [DATA_DIR]     (default: the repository's tests/data/core)
//
// Prints one line per failed check and a summary line "core: N passed, M failed"; exits
// non-zero when a check fails.
#include "check.hpp"

#include <exception>

#ifndef CD_CORE_DATA
#define CD_CORE_DATA "tests/data/core"
#endif

int main(int argc, char** argv)
{
	try {
		cdtest::localSolverTests();
		cdtest::solverTests(argc > 1 ? argv[1] : CD_CORE_DATA);
	} catch (const std::exception& e) {
		std::printf("FAILED: uncaught exception: %s\n", e.what());
		++cdtest::failed;
	}
	std::printf("core: %d passed, %d failed\n", cdtest::passed, cdtest::failed);
	return cdtest::failed ? 1 : 0;
}
