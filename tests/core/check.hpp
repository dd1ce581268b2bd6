// Core tier: the tiny check harness shared by the tests of tests/core/ (one binary,
// cd_core_tests; main.cpp prints the summary "core: N passed, M failed").
#pragma once

#include <cstdio>
#include <string>

namespace cdtest {

inline int passed = 0, failed = 0;

inline void check(bool ok, const std::string& what)
{
	if (ok) ++passed;
	else {
		++failed;
		std::printf("FAILED: %s\n", what.c_str());
	}
}

void localSolverTests();                        // test_local_solver.cpp
void solverTests(const std::string& dataDir);   // test_solver.cpp

} // namespace cdtest
