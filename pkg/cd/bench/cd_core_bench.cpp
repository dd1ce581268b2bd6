// The solver core's benchmark, without YADE: reads a saved step (a problem file, written by
// ContactDynamicsIntegrator.problemFile; format in pkg/cd/core/ProblemFile.hpp) and prints
//
//   - the step as saved: assembly, solve and correction times, and sweeps, at the file's options;
//   - ns per contact per sweep: the difference of two solves forced to K1 and K2 sweeps
//     (tolerance unreachable) divided by (K2 − K1)·contacts, each the best of --repeat, so
//     set-up, warm start and residual checks cancel (as scripts/bench/solver_bench.py does
//     inside YADE).
//
//   build/cd_core_bench FILE [--schedule 1|4|5] [--slabs N] [--slabs-across N] [--slabs-own-bodies 0|1] [--momentum 0|1] [--sphere 0|1]
//                            [--tolerance T] [--time-sweeps 0|1] [--parallel-min-contacts N]
//                            [--k1 20] [--k2 120] [--repeat 3] [--csv OUT.csv]
//                            [--history OUT.csv] [--worklist 0|1] [--worklist-threshold ETA]
//                            [--worklist-full-sweeps N] [--trace PREFIX] [--max-iter N]
//                            [--bodies-in-sweep-order 0|1] [--stall-window N]
//
// --trace writes where the work of one more solve (the file's step at the options given) goes:
// PREFIX_change.npy and PREFIX_residual.npy (float32, sweeps × contacts: every contact's update
// W_NN|Δr| in each sweep, 0 where a worklist sweep skipped it, and its natural-map residual after
// the sweep, both in m/s), PREFIX_contacts.csv (each contact's point and bodies, in the same
// order) and PREFIX_meta.json (‖q‖, tolerance, sweeps, contacts).
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
	int    sweeps, correctionSweeps, interface, fullSweeps, wide, residualChecks;
	std::string stages; // the schedule: per stage, its ranges' contact counts ('|' between stages, ' ' between ranges, 's:' before a serial stage's)
	long   contacts, updates;
	double residual;
};

// A float32 array of the given shape as a NumPy .npy file (format 1.0).
void writeNpy(const std::string& path, const std::vector<float>& data, long rows, long cols)
{
	std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(rows) + ", " + std::to_string(cols) + "), }";
	while ((10 + header.size() + 1) % 64 != 0)
		header += ' ';
	header += '\n';
	std::ofstream out(path, std::ios::binary);
	if (!out) throw std::runtime_error("cannot write " + path);
	out.write("\x93NUMPY\x01\x00", 8);
	const unsigned short len = (unsigned short)header.size();
	out.put(char(len & 0xff));
	out.put(char(len >> 8));
	out << header;
	out.write(reinterpret_cast<const char*>(data.data()), std::streamsize(data.size() * sizeof(float)));
}

// One more solve of the step with the trace on, written as --trace describes.
void writeTrace(const cd::SavedProblem& pb, cd::Params p, const std::string& prefix)
{
	p.traceContacts = true;
	cd::Solver s;
	pb.load(s);
	s.assemble(p);
	const cd::SolveStats st = s.solve(p);
	const long           nc = long(s.contacts.size()), ns = st.iterations;
	writeNpy(prefix + "_change.npy", st.traceChange, ns, nc);
	writeNpy(prefix + "_residual.npy", st.traceResidual, ns, nc);
	std::ofstream c(prefix + "_contacts.csv");
	c << "x,y,z,b1,b2,ref_radius\n";
	c.precision(9);
	for (long k = 0; k < nc; ++k) {
		const cd::ContactInfo& ci = s.contacts.info[k];
		c << ci.point[0] << ',' << ci.point[1] << ',' << ci.point[2] << ',' << ci.b1 << ',' << ci.b2 << ',' << ci.refR << '\n';
	}
	std::ofstream m(prefix + "_meta.json");
	m.precision(12);
	m << "{\"q_norm\": " << double(s.qNorm) << ", \"tolerance\": " << double(p.tolerance) << ", \"sweeps\": " << ns << ", \"contacts\": " << nc
	  << ", \"residual\": " << double(st.residual) << ", \"converged\": " << (st.converged ? "true" : "false") << ", \"worklist\": " << (p.worklist ? "true" : "false")
	  << ", \"worklist_threshold\": " << double(p.worklistThreshold) << ", \"contact_updates\": " << st.contactUpdates << ", \"full_sweeps\": " << st.fullSweeps
	  << ", \"up\": [" << p.up[0] << ", " << p.up[1] << ", " << p.up[2] << "]}\n";
	std::printf("  trace: %ld sweeps x %ld contacts written to %s_*\n", ns, nc, prefix.c_str());
}

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
	t.wide                       = st.nWide;
	const cd::Schedule& o        = s.schedule();
	for (size_t j = 0; j < o.stages.size(); ++j) {
		const cd::Schedule::Stage& stage = o.stages[j];
		if (j) t.stages += '|';
		if (!stage.parallel && stage.end - stage.begin > 1) t.stages += "s:"; // ranges swept one after the other by one thread
		for (int i = stage.begin; i < stage.end; ++i)
			t.stages += (i > stage.begin ? " " : "") + std::to_string(o.bounds[i + 1] - o.bounds[i]);
	}
	t.residual                   = double(st.residual);
	t.assemble = t1 - t0;
	t.solve    = t2 - t1;
	t.correct  = t3 - t2;
	t.sweeps   = st.iterations;
	t.fullSweeps = st.fullSweeps;
	t.residualChecks = st.residualChecks;
	t.updates  = st.contactUpdates;
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
	std::fprintf(stderr, "cd_core_bench: %s\nusage: cd_core_bench FILE [--schedule 1|4|5] [--slabs N] [--slabs-across N] [--slabs-own-bodies 0|1] [--momentum 0|1] [--sphere 0|1] [--tolerance T] [--time-sweeps 0|1] [--k1 K] [--k2 K] [--repeat R] [--csv OUT] [--history OUT] [--worklist 0|1] [--worklist-threshold ETA] [--worklist-full-sweeps N] [--trace PREFIX] [--max-iter N] [--bodies-in-sweep-order 0|1] [--stall-window N] [--check-every N]\n", what);
	std::exit(2);
}

} // namespace

int main(int argc, char** argv)
{
	if (argc < 2) usage("no problem file given");
	std::string file = argv[1], csv, history, trace;
	int         worklist = -1, workFull = -1, maxIter = -1, bodyOrder = -1, stallWindow = -1, checkEvery = -1;
	double      workThreshold = -1;
	int         k1 = 20, k2 = 120, repeat = 3;
	int         schedule = -1, slabs = -1, across = -1, owned = -1, momentum = -1, sphere = -1, timeSweeps = 1, corrMomentum = -1;
	double      tolerance = -1;
	long        parallelMin = -1;
	for (int i = 2; i < argc; ++i) {
		const std::string a = argv[i];
		if (i + 1 >= argc) usage(("missing value after " + a).c_str());
		const std::string v = argv[++i];
		if (a == "--schedule") schedule = std::stoi(v);
		else if (a == "--slabs") slabs = std::stoi(v);
		else if (a == "--slabs-across") across = std::stoi(v);
		else if (a == "--slabs-own-bodies") owned = std::stoi(v);
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
		else if (a == "--worklist") worklist = std::stoi(v);
		else if (a == "--worklist-threshold") workThreshold = std::stod(v);
		else if (a == "--worklist-full-sweeps") workFull = std::stoi(v);
		else if (a == "--trace") trace = v;
		else if (a == "--max-iter") maxIter = std::stoi(v);
		else if (a == "--bodies-in-sweep-order") bodyOrder = std::stoi(v);
		else if (a == "--stall-window") stallWindow = std::stoi(v);
		else if (a == "--check-every") checkEvery = std::stoi(v);
		else usage(("unknown option " + a).c_str());
	}
	if (!(k1 >= 1 && k2 > k1 && repeat >= 1)) usage("need 1 ≤ k1 < k2 and repeat ≥ 1");
	try {
		const cd::SavedProblem pb = cd::readProblemFile(file);
		cd::Params             p  = pb.params;
		if (schedule >= 0) p.schedule = schedule;
		if (slabs >= 0) p.slabs = slabs;
		if (across >= 0) p.slabsAcross = across;
		if (owned >= 0) p.slabsOwnBodies = owned;
		if (momentum >= 0) p.momentum = momentum;
		if (sphere >= 0) p.sphereFastPath = sphere;
		if (tolerance > 0) p.tolerance = tolerance;
		if (corrMomentum >= 0) p.correctionMomentum = corrMomentum;
		if (parallelMin >= 0) p.parallelMinContacts = parallelMin;
		if (maxIter > 0) p.maxIter = maxIter;
		if (bodyOrder >= 0) p.bodiesInSweepOrder = bodyOrder;
		if (stallWindow > 0) p.stallWindow = stallWindow;
		if (checkEvery > 0) p.checkEvery = checkEvery;
		if (worklist >= 0) p.worklist = worklist;
		if (workThreshold > 0) p.worklistThreshold = workThreshold;
		if (workFull >= 0) p.worklistFullSweeps = workFull;
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
			// a difference of two timings: on a small step or a busy machine the noise can exceed it, and a zero or
			// negative difference says nothing about the cost: no figure (NaN, as without --time-sweeps), here and in --csv
			if (!(ns > 0)) ns = std::nan("");
		}
		std::printf("%s: %zu bodies, %ld contacts; schedule %d, slabs %d x %d, momentum %d, sphere kernel %d, %d thread(s)\n", file.c_str(),
		            pb.bodies.size(), step.contacts, p.schedule, p.slabs, p.slabsAcross, int(p.momentum), int(p.sphereFastPath), threads);
		std::printf("  step at the file's tolerance %g: %d sweeps (%d full; %ld contact updates, %.1f sweeps' worth; residual %.3g, %d residual checks), %d correction sweeps, %d interface contacts; assemble %.3f ms, solve %.3f ms, correct %.3f ms\n",
		            double(p.tolerance), step.sweeps, step.fullSweeps, step.updates, double(step.updates) / double(std::max(step.contacts, 1L)), step.residual, step.residualChecks, step.correctionSweeps,
		            step.interface, step.assemble * 1e3, step.solve * 1e3, step.correct * 1e3);
		std::printf("  schedule: %s (%d interface contacts, %d of them touching three parts or more)\n", step.stages.c_str(), step.interface, step.wide);
		if (p.worklist) std::printf("  worklist: threshold %g x tolerance x |q| / sqrt(contacts), %d full sweeps first\n", double(p.worklistThreshold), p.worklistFullSweeps);
		if (timeSweeps) {
			if (!std::isnan(ns)) std::printf("  time per contact-sweep: %.2f ns (sweeps %d and %d, best of %d)\n", ns, k1, k2, repeat);
			else
				std::printf("  time per contact-sweep: not resolved (the solve with %d sweeps took no longer than with %d: timer noise; "
				            "raise --repeat or --k2)\n", k2, k1);
		}
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
		if (!trace.empty()) writeTrace(pb, p, trace);
		if (!csv.empty()) {
			std::ifstream exists(csv);
			const bool    header = !exists.good();
			std::ofstream out(csv, std::ios::app);
			if (header) out << "file,bodies,contacts,schedule,slabs,momentum,sphere,threads,tolerance,sweeps,residual,correction_sweeps,interface,assemble_ms,solve_ms,correct_ms,ns_per_contact_sweep,worklist,worklist_threshold,full_sweeps,contact_updates,bodies_in_sweep_order,wide,stages,slabs_across,residual_checks,check_every,slabs_own_bodies\n";
			out << file << ',' << pb.bodies.size() << ',' << step.contacts << ',' << p.schedule << ',' << p.slabs << ',' << int(p.momentum) << ','
			    << int(p.sphereFastPath) << ',' << threads << ',' << double(p.tolerance) << ',' << step.sweeps << ',' << step.residual << ','
			    << step.correctionSweeps << ',' << step.interface << ',' << step.assemble * 1e3 << ','
			    << step.solve * 1e3 << ',' << step.correct * 1e3 << ',' << ns << ',' << int(p.worklist) << ',' << double(p.worklistThreshold) << ','
			    << step.fullSweeps << ',' << step.updates << ',' << int(p.bodiesInSweepOrder) << ',' << step.wide << ',' << step.stages << ',' << p.slabsAcross << ',' << step.residualChecks << ',' << p.checkEvery << ',' << int(p.slabsOwnBodies) << '\n';
		}
	} catch (const std::exception& e) {
		std::fprintf(stderr, "cd_core_bench: %s\n", e.what());
		return 1;
	}
	return 0;
}
