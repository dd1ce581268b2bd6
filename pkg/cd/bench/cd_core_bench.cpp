// The solver core's benchmark, without YADE: reads a saved step (a problem file, written by
// ContactDynamicsIntegrator.problemFile; format in pkg/cd/core/ProblemFile.hpp) and prints
//
//   - the step as saved: assembly, solve and correction times, and sweeps, at the file's options;
//   - ns per contact per sweep: the difference of two solves forced to K1 and K2 sweeps
//     (tolerance unreachable) divided by (K2 − K1)·contacts, each the best of --repeat, so
//     set-up, warm start and residual checks cancel (as scripts/bench/solver_bench.py does
//     inside YADE).
//
//   build/cd_core_bench FILE [--schedule 1|4|5] [--slabs N] [--momentum 0|1] [--sphere 0|1]
//                            [--tolerance T] [--time-sweeps 0|1] [--parallel-min-contacts N]
//                            [--k1 20] [--k2 120] [--repeat 3] [--csv OUT.csv]
//                            [--history OUT.csv]
//
// --history writes the residual after every sweep of one more solve (the exact residual evaluated
// at each sweep, which may stop that solve a sweep or two earlier than the timed one).
// Options not given keep the file's values. Threads: OMP_NUM_THREADS (the parallel schedules
// give the same results for any count).
#include "core/ProblemFile.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>
#ifdef _OPENMP
#include <omp.h>
#endif

using namespace yade;

namespace {

double seconds()
{
	using namespace std::chrono;
	return duration<double>(steady_clock::now().time_since_epoch()).count();
}

struct StepTimes {
	double assemble, solve, correct;
	int    sweeps, correctionSweeps, interface;
	long   contacts;
	double residual;
};

StepTimes runStep(const cd::SavedProblem& pb, const cd::Params& p)
{
	cd::Solver s;
	pb.load(s);
	StepTimes t;
	double    t0 = seconds();
	s.assemble(p);
	double t1 = seconds();
	const cd::SolveStats st = s.solve(p);
	double t2 = seconds();
	const cd::CorrectionStats cs = s.correct(p);
	double                    t3 = seconds();
	t.correctionSweeps           = cs.iterations;
	t.interface                  = st.nInterface;
	t.residual                   = double(st.residual);
	t.assemble = t1 - t0;
	t.solve    = t2 - t1;
	t.correct  = t3 - t2;
	t.sweeps   = st.iterations;
	t.contacts = long(s.contacts.size());
	return t;
}

double bestForcedSolve(const cd::SavedProblem& pb, cd::Params p, int sweeps, int repeat)
{
	p.tolerance  = 1e-300;
	p.maxIter    = sweeps;
	double best  = 1e300;
	for (int i = 0; i < repeat; ++i) {
		const StepTimes t = runStep(pb, p);
		if (t.sweeps != sweeps) throw std::runtime_error("a forced solve stopped early");
		best = std::min(best, t.solve);
	}
	return best;
}

[[noreturn]] void usage(const char* what)
{
	std::fprintf(stderr, "cd_core_bench: %s\nusage: cd_core_bench FILE [--schedule 1|4|5] [--slabs N] [--momentum 0|1] [--sphere 0|1] [--tolerance T] [--time-sweeps 0|1] [--k1 K] [--k2 K] [--repeat R] [--csv OUT] [--history OUT]\n", what);
	std::exit(2);
}

} // namespace

int main(int argc, char** argv)
{
	if (argc < 2) usage("no problem file given");
	std::string file = argv[1], csv, history;
	int         k1 = 20, k2 = 120, repeat = 3;
	int         schedule = -1, slabs = -1, momentum = -1, sphere = -1, timeSweeps = 1, corrMomentum = -1;
	double      tolerance = -1;
	long        parallelMin = -1;
	for (int i = 2; i < argc; ++i) {
		const std::string a = argv[i];
		if (i + 1 >= argc) usage(("missing value after " + a).c_str());
		const std::string v = argv[++i];
		if (a == "--schedule") schedule = std::stoi(v);
		else if (a == "--slabs") slabs = std::stoi(v);
		else if (a == "--momentum") momentum = std::stoi(v);
		else if (a == "--sphere") sphere = std::stoi(v);
		else if (a == "--tolerance") tolerance = std::stod(v);
		else if (a == "--correction-momentum") corrMomentum = std::stoi(v);
		else if (a == "--time-sweeps") timeSweeps = std::stoi(v);
		else if (a == "--parallel-min-contacts") parallelMin = std::stol(v);
		else if (a == "--k1") k1 = std::stoi(v);
		else if (a == "--k2") k2 = std::stoi(v);
		else if (a == "--repeat") repeat = std::stoi(v);
		else if (a == "--csv") csv = v;
		else if (a == "--history") history = v;
		else usage(("unknown option " + a).c_str());
	}
	if (!(k1 >= 1 && k2 > k1 && repeat >= 1)) usage("need 1 ≤ k1 < k2 and repeat ≥ 1");
	try {
		const cd::SavedProblem pb = cd::readProblemFile(file);
		cd::Params             p  = pb.params;
		if (schedule >= 0) p.schedule = schedule;
		if (slabs >= 0) p.slabs = slabs;
		if (momentum >= 0) p.momentum = momentum;
		if (sphere >= 0) p.sphereFastPath = sphere;
		if (tolerance > 0) p.tolerance = tolerance;
		if (corrMomentum >= 0) p.correctionMomentum = corrMomentum;
		if (parallelMin >= 0) p.parallelMinContacts = parallelMin;
		int threads = 1;
#ifdef _OPENMP
		threads = omp_get_max_threads();
#endif
		StepTimes step = runStep(pb, p); // first run: memory touched once
		step           = runStep(pb, p);
		double ns = std::nan("");
		if (timeSweeps) {
			const double t1 = bestForcedSolve(pb, p, k1, repeat), t2 = bestForcedSolve(pb, p, k2, repeat);
			ns              = (t2 - t1) / (k2 - k1) / double(step.contacts) * 1e9;
		}
		std::printf("%s: %zu bodies, %ld contacts; schedule %d, slabs %d, momentum %d, sphere kernel %d, %d thread(s)\n", file.c_str(),
		            pb.bodies.size(), step.contacts, p.schedule, p.slabs, int(p.momentum), int(p.sphereFastPath), threads);
		std::printf("  step at the file's tolerance %g: %d sweeps (residual %.3g), %d correction sweeps, %d interface contacts; assemble %.3f ms, solve %.3f ms, correct %.3f ms\n",
		            double(p.tolerance), step.sweeps, step.residual, step.correctionSweeps, step.interface, step.assemble * 1e3, step.solve * 1e3, step.correct * 1e3);
		if (timeSweeps) std::printf("  time per contact-sweep: %.2f ns (sweeps %d and %d, best of %d)\n", ns, k1, k2, repeat);
		if (!history.empty()) {
			cd::Params q     = p;
			q.recordResidual = true;
			cd::Solver s;
			pb.load(s);
			s.assemble(q);
			const cd::SolveStats st = s.solve(q);
			std::ofstream        out(history);
			out << "sweep,residual\n";
			for (size_t i = 0; i < st.residualHistory.size(); ++i)
				out << (i + 1) * q.checkEvery << ',' << double(st.residualHistory[i]) << '\n';
			std::printf("  residual history: %zu sweeps written to %s\n", st.residualHistory.size(), history.c_str());
		}
		if (!csv.empty()) {
			std::ifstream exists(csv);
			const bool    header = !exists.good();
			std::ofstream out(csv, std::ios::app);
			if (header) out << "file,bodies,contacts,schedule,slabs,momentum,sphere,threads,tolerance,sweeps,residual,correction_sweeps,interface,assemble_ms,solve_ms,correct_ms,ns_per_contact_sweep\n";
			out << file << ',' << pb.bodies.size() << ',' << step.contacts << ',' << p.schedule << ',' << p.slabs << ',' << int(p.momentum) << ','
			    << int(p.sphereFastPath) << ',' << threads << ',' << double(p.tolerance) << ',' << step.sweeps << ',' << step.residual << ','
			    << step.correctionSweeps << ',' << step.interface << ',' << step.assemble * 1e3 << ','
			    << step.solve * 1e3 << ',' << step.correct * 1e3 << ',' << ns << '\n';
		}
	} catch (const std::exception& e) {
		std::fprintf(stderr, "cd_core_bench: %s\n", e.what());
		return 1;
	}
	return 0;
}
