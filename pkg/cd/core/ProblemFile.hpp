// Contact Dynamics solver core: one step's problem as a text file, exact to the last bit.
//
// The file holds the core's input at stage 5 (what the host has filled in after stages 1–4:
// bodies with their free velocities, contacts with their frames, gaps and warm starts) and the
// solver's options, so that the core can solve the same step again without YADE: the core
// tests (tests/core/) and the core benchmark (cd_core_bench) read such files. YADE writes one
// with ContactDynamicsIntegrator.problemFile; scripts/core_problems.py makes the test set.
//
//   cdproblem 1
//   params h ux uy uz tolerance maxIter checkEvery relaxation schedule slabs momentum sphereFastPath positionTolerance maxProjectionIter
//          [1 [A [1]]]   (correctionMomentum, absent: 0, as in files written before it existed;
//                          then slabsAcross, absent: 1; then slabsOwnBodies, absent: 0)
//   bodies N
//   body id dynamic isoInvM isoInvI v(3) w(3) invM(3) invI(9, row-major) vi(3) wi(3)        (N lines)
//   contacts M
//   contact b1 b2 mu status frame(9) c1(3) c2(3) point(3) height gapI gapM refR allowance en et approach(3) warmStart(3)
//           [shift(3)]   (body 2 through its periodic image: the image's shift velocity, Cell.intrShiftVel; absent: none)
//   ... then any number of lines the host appends, kept as text (Problem::extra), e.g.
//   expect ...           (tests/core: exact answers, the engine's own results)
//
// Numbers are written with max_digits10 digits: reading them back gives the same bits.
#pragma once

#include "Solver.hpp"

#include <iosfwd>
#include <string>

namespace yade {
namespace cd {

	/*! A saved step: the core's input and the options, plus the lines appended after them. */
	struct SavedProblem {
		Params                   params;
		std::vector<Body>        bodies;
		std::vector<BodyRecord>  records;
		ContactSet               contacts; // info, mu and status filled; kernels and impulses not yet
		std::vector<std::string> extra;    // appended lines, verbatim

		/*! Load this problem into a solver (which is then ready for stage 5). */
		void load(Solver& solver) const;
	};

	/*! Write the solver's current input (call between stages 4 and 5) and the options. */
	void writeProblem(std::ostream& out, const Solver& solver, const Params& params);
	/*! Read a problem file; throws std::runtime_error naming the line on malformed input. */
	SavedProblem readProblem(std::istream& in);
	SavedProblem readProblemFile(const std::string& path);

} // namespace cd
} // namespace yade
