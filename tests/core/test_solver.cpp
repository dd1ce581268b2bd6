// Core tier: the solver core (pkg/cd/core/Solver.hpp) on saved steps (tests/data/core/*.cdp,
// written by YADE through ContactDynamicsIntegrator.problemFile; scripts/core_problems.py makes
// them), without YADE. For every file:
//
//  1. the engine's own step, reproduced: solved with the options it was saved with, the core
//     gives the impulses, velocities and sweep count that YADE's engine gave, bit for bit;
//  2. a grid of options (schedules height, colours, slabs, slabs cut into columns × momentum on/off × sphere/general
//     kernel), each solved tightly (1e-10, or the file's grid_tolerance), checked against the law in matrix form: Ũ = W r + q with W
//     from delassusTriplets and q from the free velocities, the natural-map residual of every
//     contact (an evaluation independent of the sweep's kernels), against the file's exact
//     answers (`expect_impulse`, `expect_load`), and the velocities against those of the first
//     option (the same step solved in another order converges to the same motion);
//  3. the file written back is the file read.
#include "check.hpp"
#include "core/LocalSolver.hpp"
#include "core/ProblemFile.hpp"

#include <algorithm>
#include <cmath>
#include <dirent.h>
#include <fstream>
#include <cstdio>
#include <map>
#include <sstream>
#include <tuple>

using namespace yade;
using cdtest::check;

namespace {

std::string num(double x)
{
	char b[32];
	std::snprintf(b, sizeof b, "%.3g", x);
	return b;
}

using Pair     = std::pair<int, int>;
using Impulses = std::map<Pair, std::vector<Vector3r>>; // by the pair of bodies moved, in the host's contact order

struct Expectations {
	std::map<Pair, std::vector<Vector3r>>      engineImpulse; // by bodies moved (a clump for its members), in the engine's contact order
	std::map<int, std::pair<Vector3r, Vector3r>> engineVelocity;
	int                                        engineSweeps = -1;
	std::vector<std::pair<Pair, std::pair<Vector3r, Real>>> impulse; // exact impulse on body 2, tolerance
	std::vector<std::pair<std::vector<int>, std::pair<Vector3r, Real>>> load; // exact total impulse on a set of bodies, tolerance
	std::string                                description;
	double                                     gridTolerance = 1e-10; // the option grid's solver tolerance
};

Vector3r readVec(std::istringstream& s)
{
	Real x, y, z;
	s >> x >> y >> z;
	return Vector3r(x, y, z);
}

Expectations parseExtra(const std::vector<std::string>& lines)
{
	Expectations e;
	for (const std::string& line : lines) {
		std::istringstream s(line);
		std::string        key;
		s >> key;
		if (key == "engine_impulse") {
			int b1, b2;
			s >> b1 >> b2;
			e.engineImpulse[{ b1, b2 }].push_back(readVec(s));
		} else if (key == "engine_velocity") {
			int id;
			s >> id;
			const Vector3r v = readVec(s);
			e.engineVelocity[id] = { v, readVec(s) };
		} else if (key == "engine_sweeps") {
			s >> e.engineSweeps;
		} else if (key == "expect_impulse") {
			int b1, b2;
			s >> b1 >> b2;
			const Vector3r P = readVec(s);
			Real           tol;
			s >> tol;
			e.impulse.push_back({ { b1, b2 }, { P, tol } });
		} else if (key == "expect_load") { // ids comma-separated: the total over those bodies
			std::string      list, id;
			std::vector<int> ids;
			s >> list;
			std::istringstream l(list);
			while (std::getline(l, id, ','))
				ids.push_back(std::stoi(id));
			const Vector3r P = readVec(s);
			Real           tol;
			s >> tol;
			e.load.push_back({ ids, { P, tol } });
		} else if (key == "grid_tolerance") {
			s >> e.gridTolerance;
		} else if (key == "describe") {
			std::getline(s, e.description);
		}
	}
	return e;
}

// The law in matrix form after a solve: Ũ = W r + q, W from the solver's Delassus triplets,
// q_k = A(U_free + s) saved by the caller (indexed by the contact's origin). Returns the
// relative natural-map residual sqrt(Σ|e_k|²)/‖q‖ (ρ_k = 1/W̃_kk,NN).
Real matrixLawResidual(const cd::Solver& s, const std::vector<Vector3r>& qByOrigin)
{
	std::vector<long>   rows, cols;
	std::vector<double> vals;
	s.delassusTriplets(rows, cols, vals);
	const size_t          nc = s.contacts.size();
	std::vector<Vector3r> U(nc);
	std::vector<Real>     wnn(nc, 0);
	for (size_t k = 0; k < nc; ++k)
		U[k] = qByOrigin[s.contacts.info[k].origin];
	for (size_t t = 0; t < vals.size(); ++t) {
		U[rows[t] / 3][rows[t] % 3] += vals[t] * s.contacts.state[cols[t] / 3].r[cols[t] % 3];
		if (rows[t] == cols[t] && rows[t] % 3 == 0) wnn[rows[t] / 3] += vals[t];
	}
	Real sum = 0, qq = 0;
	for (size_t k = 0; k < nc; ++k) {
		sum += cd::naturalMapResidual(s.contacts.state[k].r, U[k], s.contacts.state[k].mu, 1 / wnn[k]).squaredNorm();
		const Vector3r& q = qByOrigin[s.contacts.info[k].origin];
		if (q[0] < 0) qq += q.squaredNorm();
	}
	return std::sqrt(sum) / (qq > 0 ? std::sqrt(qq) : 1.0);
}

// Global impulses by the pair of bodies the solve moves, in the host's contact order (origin):
// two clumps may touch at several points, so a pair holds a list.
Impulses globalImpulses(const cd::Solver& s)
{
	std::vector<size_t> byOrigin(s.contacts.size());
	for (size_t k = 0; k < s.contacts.size(); ++k)
		byOrigin[k] = k;
	std::sort(byOrigin.begin(), byOrigin.end(), [&](size_t a, size_t b) { return s.contacts.info[a].origin < s.contacts.info[b].origin; });
	std::map<Pair, std::vector<Vector3r>> out;
	for (size_t k : byOrigin) {
		const cd::ContactInfo& c = s.contacts.info[k];
		out[{ c.b1, c.b2 }].push_back(c.frame.transpose() * s.contacts.state[k].r); // as storeResults writes CDPhys.impulse
	}
	return out;
}

void reproduceEngine(const std::string& name, const cd::SavedProblem& pb, const Expectations& e)
{
	cd::Solver s;
	pb.load(s);
	s.assemble(pb.params);
	const cd::SolveStats st = s.solve(pb.params);
	s.correct(pb.params);
	check(e.engineSweeps >= 0 && !e.engineImpulse.empty(), name + ": the file holds the engine's results");
	check(st.iterations == e.engineSweeps, name + ": the engine's sweep count (" + std::to_string(e.engineSweeps) + "), got " + std::to_string(st.iterations));
	// per pair of bodies, as sets: the engine's list is in the interaction container's order,
	// which need not be the order the engine gathered several contacts of two clumps in
	auto sorted = [](std::vector<Vector3r> v) {
		std::sort(v.begin(), v.end(), [](const Vector3r& a, const Vector3r& b) { return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3); });
		return v;
	};
	const auto P    = globalImpulses(s);
	bool       same = P.size() == e.engineImpulse.size();
	for (const auto& [pair, value] : e.engineImpulse)
		same = same && P.count(pair) && sorted(P.at(pair)) == sorted(value);
	check(same, name + ": the engine's impulses, bit for bit");
	bool sameV = !e.engineVelocity.empty();
	for (const auto& [id, vw] : e.engineVelocity)
		sameV = sameV && s.bodies[id].v == vw.first && s.bodies[id].w == vw.second;
	check(sameV, name + ": the engine's velocities u_f, bit for bit");
}

void optionGrid(const std::string& name, const cd::SavedProblem& pb, const Expectations& e)
{
	std::vector<Vector3r> vRef;
	Real                  vScale = 0;
	// {schedule, columns per slab, bodies owned by parts}; 5, 3: slabs cut into three columns each
	for (const auto& [schedule, across, owned] : std::vector<std::tuple<int, int, bool>> { { 1, 1, false }, { 4, 1, false }, { 5, 1, false }, { 5, 3, false }, { 5, 1, true }, { 5, 3, true } })
		for (int momentum : { 1, 0 })
			for (int sphere : { 1, 0 }) {
				cd::Params p   = pb.params;
				p.schedule     = schedule;
				p.slabsAcross  = across;
				p.slabsOwnBodies = owned;
				p.momentum     = momentum;
				p.sphereFastPath = sphere;
				p.relaxation   = 1;
				p.tolerance    = e.gridTolerance;
				p.maxIter      = 100000;
				const std::string what = name + " [schedule " + std::to_string(schedule) + (across > 1 ? " x " + std::to_string(across) + " columns" : "") + (owned ? ", bodies owned" : "") + (momentum ? ", momentum" : "") + (sphere ? ", sphere kernel" : ", general kernel") + "]";
				cd::Solver s;
				pb.load(s);
				s.assemble(p);
				std::vector<Vector3r> q(s.contacts.size());
				for (size_t k = 0; k < s.contacts.size(); ++k) {
					const cd::ContactInfo& c     = s.contacts.info[k];
					q[c.origin]                  = c.A.cwiseProduct(s.localVelocity(long(k)) + c.s);
				}
				const cd::SolveStats st = s.solve(p);
				check(st.converged, what + ": converges to " + num(p.tolerance) + " (residual " + num(st.residual) + ")");
				const Real law = matrixLawResidual(s, q);
				check(law <= 2 * p.tolerance, what + ": the law in matrix form holds (relative natural-map residual " + num(law) + ")");
				const auto P = globalImpulses(s);
				for (const auto& [pair, exp] : e.impulse) {
					const Real err = P.count(pair) && P.at(pair).size() == 1 ? (P.at(pair)[0] - exp.first).norm() : INFINITY;
					check(err <= exp.second, what + ": exact impulse of (" + std::to_string(pair.first) + ", " + std::to_string(pair.second) + "), error " + std::to_string(err));
				}
				for (const auto& [ids, exp] : e.load) {
					Vector3r    total = Vector3r::Zero();
					std::string who;
					for (int id : ids) {
						who += (who.empty() ? "#" : ", #") + std::to_string(id);
						for (const auto& [pair, list] : P)
							for (const Vector3r& Pk : list)
								total += (pair.second == id ? Pk : Vector3r::Zero()) - (pair.first == id ? Pk : Vector3r::Zero());
					}
					const Real err = (total - exp.first).norm();
					check(err <= exp.second, what + ": exact total impulse on " + who + ", error " + num(err));
				}
				std::vector<Vector3r> v;
				for (size_t b = 0; b < s.bodies.size(); ++b)
					if (s.records[b].dynamic) v.push_back(s.bodies[b].v), v.push_back(s.bodies[b].w * (pb.contacts.size() ? pb.contacts.info.front().refR : 1.0));
				if (vRef.empty()) {
					vRef = v;
					for (const Vector3r& x : v)
						vScale = std::max(vScale, x.norm());
					vScale = std::max(vScale, pb.params.h * 9.81);
					continue;
				}
				Real dv = 0;
				for (size_t i = 0; i < v.size(); ++i)
					dv = std::max(dv, (v[i] - vRef[i]).norm());
				check(dv <= 1e4 * p.tolerance * vScale, what + ": the same motion as the first option (relative difference " + num(dv / vScale) + ")");
			}
}

// The end-of-step overlap beyond the allowance of every contact after the position correction,
// relative to its reference radius: (−a − g_m − h/2 (U_N + Ũ_N))/refR with Ũ from the bodies'
// pseudo-velocities (records[b].pv, .pw), computed here from the definitions, not by the solver.
std::vector<Real> finalOverlaps(const cd::Solver& s, Real h)
{
	std::vector<Real> out(s.contacts.size());
	for (size_t k = 0; k < s.contacts.size(); ++k) {
		const cd::ContactInfo& c  = s.contacts.info[k];
		const cd::BodyRecord & r1 = s.records[c.b1], &r2 = s.records[c.b2];
		const Real pseudoN = (c.frame * ((r2.pv + r2.pw.cross(c.c2)) - (r1.pv + r1.pw.cross(c.c1))))[0];
		out[k]             = (-c.allowance - c.gapM - 0.5 * h * (s.localVelocity(long(k))[0] + pseudoN)) / c.refR;
	}
	return out;
}

// The position correction, plain and with momentum, on a step that needs one: every overlap
// beyond its allowance removed to positionTolerance, and the same pseudo-velocities from both
// (the frictionless projection's velocity, M⁻¹HP, is unique even where P is not).
// Returns whether the step had anything to correct (the checks ran).
bool correctionCheck(const std::string& name, const cd::SavedProblem& pb)
{
	std::vector<std::vector<Vector3r>> pv;
	std::vector<int>                   sweeps;
	Real                               before = 0;
	for (bool momentum : { false, true }) {
		cd::Params p         = pb.params;
		p.correctionMomentum = momentum;
		p.maxProjectionIter  = 100000;
		cd::Solver s;
		pb.load(s);
		s.assemble(p);
		s.solve(p);
		const cd::CorrectionStats st = s.correct(p);
		before                       = st.maxOverlap;
		if (st.iterations == 0) return false; // nothing to correct in this step
		const std::string what  = name + (momentum ? " [correction with momentum]" : " [plain correction]");
		Real              worst = 0;
		for (Real v : finalOverlaps(s, p.h))
			worst = std::max(worst, v);
		check(st.iterations < p.maxProjectionIter, what + ": converges (" + std::to_string(st.iterations) + " sweeps)");
		check(worst <= p.positionTolerance * (1 + 1e-9), what + ": overlap " + num(before) + " removed to the tolerance " + num(p.positionTolerance) + " (left " + num(worst) + ")");
		std::vector<Vector3r> v;
		for (size_t b = 0; b < s.bodies.size(); ++b)
			v.push_back(s.records[b].pv);
		pv.push_back(v);
		sweeps.push_back(st.iterations);
	}
	// both stop within positionTolerance of the constraints: pseudo-displacements h/2·Ũ agree to
	// a small multiple of it (relative to the smallest reference radius)
	Real refR = INFINITY, diff = 0;
	for (size_t k = 0; k < pb.contacts.size(); ++k)
		refR = std::min(refR, pb.contacts.info[k].refR);
	for (size_t b = 0; b < pv[0].size(); ++b)
		diff = std::max(diff, 0.5 * pb.params.h * (pv[0][b] - pv[1][b]).norm() / refR);
	check(diff <= 10 * pb.params.positionTolerance, name + ": plain and accelerated corrections give the same pseudo-displacements (difference " + num(diff) + " of a radius; sweeps " + std::to_string(sweeps[0]) + " and " + std::to_string(sweeps[1]) + ")");
	return true;
}

// The per-sweep stages on threads or on the calling thread (Params::parallelMinContacts 0 or
// above the contact count): the same step, bit for bit, for the parallel schedules (colours,
// slabs), with momentum in the solve and in the correction.
void threadsCheck(const std::string& name, const cd::SavedProblem& pb)
{
	// 15: slabs with the worklist; 25: eight slabs (the cuts' parallel stages); 35: 4 x 4 columns;
	// 125, 135: 25 and 35 with bodies owned by parts
	for (int variant : { 4, 5, 15, 25, 35, 125, 135 }) {
		const int  schedule = variant % 10;
		const int  kind     = variant / 10 % 10;
		const bool owned    = variant >= 100;
		const bool worklist = kind == 1;
		const int  slabs    = kind >= 2 ? (kind == 2 ? 8 : 4) : pb.params.slabs;
		const int  across   = kind == 3 ? 4 : 1;
		std::vector<std::vector<Vector3r>> v, pv;
		std::vector<Impulses> P;
		std::vector<int> sweeps, corr;
		for (long minContacts : { 0L, long(pb.contacts.size()) + 1 }) {
			cd::Params p          = pb.params;
			p.schedule            = schedule;
			p.worklist            = worklist;
			p.slabs               = slabs;
			p.slabsAcross         = across;
			p.slabsOwnBodies      = owned;
			p.correctionMomentum  = true;
			p.parallelMinContacts = minContacts;
			cd::Solver s;
			pb.load(s);
			s.assemble(p);
			sweeps.push_back(s.solve(p).iterations);
			corr.push_back(s.correct(p).iterations);
			P.push_back(globalImpulses(s));
			std::vector<Vector3r> vb, pvb;
			for (size_t b = 0; b < s.bodies.size(); ++b) {
				vb.push_back(s.bodies[b].v);
				vb.push_back(s.bodies[b].w);
				pvb.push_back(s.records[b].pv);
			}
			v.push_back(vb);
			pv.push_back(pvb);
		}
		check(sweeps[0] == sweeps[1] && corr[0] == corr[1] && P[0] == P[1] && v[0] == v[1] && pv[0] == pv[1],
		      name + " [schedule " + std::to_string(schedule) + (worklist ? ", worklist" : "") + (kind == 2 ? ", 8 slabs" : "") + (kind == 3 ? ", 4 x 4 columns" : "") + (owned ? ", bodies owned" : "") + "]: threaded and serial sweeps give the same step, bit for bit (" +
		              std::to_string(sweeps[0]) + " sweeps)");
	}
}

// Sweeps that follow the work (Params::worklist), tightly solved in every schedule with and
// without momentum, at two thresholds: converged by the exact residual (never by a quiet partial
// sweep), the law in matrix form, the file's exact answers, the motion of the plain solve, and
// fewer local updates than sweeps × contacts whenever a partial sweep ran.
void worklistCheck(const std::string& name, const cd::SavedProblem& pb, const Expectations& e)
{
	// one solve of each kind: the reference (full sweeps, momentum, height order) first
	auto run = [&](int schedule, bool momentum, bool worklist, Real eta, cd::SolveStats& stats, Real& law, Impulses& P) {
		cd::Params p        = pb.params;
		p.schedule          = schedule;
		p.momentum          = momentum;
		p.relaxation        = 1;
		p.tolerance         = e.gridTolerance;
		p.maxIter           = 400000; // plain Gauss–Seidel takes 91 172 sweeps on pile300_fed at 1e-7
		p.worklist          = worklist;
		p.worklistThreshold = eta;
		cd::Solver s;
		pb.load(s);
		s.assemble(p);
		std::vector<Vector3r> q(s.contacts.size());
		for (size_t k = 0; k < s.contacts.size(); ++k)
			q[s.contacts.info[k].origin] = s.contacts.info[k].A.cwiseProduct(s.localVelocity(long(k)) + s.contacts.info[k].s);
		stats = s.solve(p);
		law   = matrixLawResidual(s, q);
		P     = globalImpulses(s);
		std::vector<Vector3r> v;
		for (size_t b = 0; b < s.bodies.size(); ++b)
			if (s.records[b].dynamic) v.push_back(s.bodies[b].v);
		return v;
	};
	cd::SolveStats           stats;
	Real                     law;
	Impulses P;
	const auto               vRef   = run(1, true, false, 1, stats, law, P);
	Real                     vScale = pb.params.h * 9.81;
	for (const Vector3r& x : vRef)
		vScale = std::max(vScale, x.norm());
	for (int schedule : { 1, 4, 5 })
		for (int momentum : { 1, 0 })
			for (Real eta : { 1.0, 10.0 }) {
				const auto        v    = run(schedule, momentum, true, eta, stats, law, P);
				const std::string what = name + " [worklist, schedule " + std::to_string(schedule) + (momentum ? ", momentum" : "") + ", threshold " + num(eta) + "]";
				const long        all  = long(stats.iterations) * long(pb.contacts.size());
				check(stats.converged && stats.residual <= e.gridTolerance, what + ": converges to " + num(e.gridTolerance) + " (residual " + num(stats.residual) + ", " +
				                                                                    std::to_string(stats.iterations) + " sweeps, " + std::to_string(stats.fullSweeps) + " full)");
				check(law <= 2 * e.gridTolerance, what + ": the law in matrix form holds (" + num(law) + ")");
				check(stats.fullSweeps >= 1 && stats.contactUpdates <= all && (stats.fullSweeps < stats.iterations || stats.contactUpdates == all),
				      what + ": partial sweeps make fewer updates (" + std::to_string(stats.contactUpdates) + " in " + std::to_string(stats.iterations) + " sweeps, " +
				              std::to_string(stats.fullSweeps) + " full)");
				for (const auto& [pair, exp] : e.impulse) {
					const Real err = P.count(pair) && P.at(pair).size() == 1 ? (P.at(pair)[0] - exp.first).norm() : INFINITY;
					check(err <= exp.second, what + ": exact impulse of (" + std::to_string(pair.first) + ", " + std::to_string(pair.second) + "), error " + num(err));
				}
				Real dv = 0;
				for (size_t i = 0; i < v.size(); ++i)
					dv = std::max(dv, (v[i] - vRef[i]).norm());
				check(dv <= 1e4 * e.gridTolerance * vScale, what + ": the motion of full sweeps (relative difference " + num(dv / vScale) + ")");
			}
}

// The trace (Params::traceContacts) changes nothing in the solve, bit for bit, and its numbers are
// the solve's: the last sweep's residuals give the reported residual, the changes are zero exactly
// where a worklist sweep made no update.
void traceCheck(const std::string& name, const cd::SavedProblem& pb)
{
	for (bool worklist : { false, true }) {
		std::vector<Impulses> P;
		std::vector<cd::SolveStats>           st;
		Real                                  q = 0;
		for (bool trace : { false, true }) {
			cd::Params p    = pb.params;
			p.worklist      = worklist;
			p.traceContacts = trace;
			cd::Solver s;
			pb.load(s);
			s.assemble(p);
			st.push_back(s.solve(p));
			P.push_back(globalImpulses(s));
			q = s.qNorm > 0 ? s.qNorm : 1;
		}
		const long        nc   = long(pb.contacts.size());
		const std::string what = name + (worklist ? " [trace, worklist]" : " [trace]");
		check(P[0] == P[1] && st[0].iterations == st[1].iterations && st[0].residual == st[1].residual && st[1].traceChange.size() == size_t(nc * st[1].iterations),
		      what + ": the same solve with the trace on, bit for bit (" + std::to_string(st[1].iterations) + " sweeps)");
		if (nc == 0) continue;
		double sum = 0;
		for (long k = 0; k < nc; ++k)
			sum += double(st[1].traceResidual[(st[1].iterations - 1) * nc + k]) * st[1].traceResidual[(st[1].iterations - 1) * nc + k];
		const double res = std::sqrt(sum) / double(q);
		check(std::abs(res - double(st[1].residual)) <= 1e-5 * double(st[1].residual) + 1e-30, what + ": the last sweep's residuals give the solve's (" + num(res) + " against " + num(st[1].residual) + ")");
		long visits = 0;
		for (float x : st[1].traceChange)
			visits += x != 0;
		check(visits <= st[1].contactUpdates, what + ": no change where no update was made (" + std::to_string(visits) + " changes, " + std::to_string(st[1].contactUpdates) + " updates)");
	}
}

// The schedules' invariant: the ranges of a parallel stage share no dynamic body (what lets it
// run them at once; a serial stage, such as the slabs' colours too small for threads, may hold
// ranges that do), and the ranges cover every contact once, for the colours, for the slabs at 2
// to 64 slabs (the cut stages included) and for slabs cut into columns, with the bodies divided
// either way. With bodies owned by parts the interface is a subset of the other's (a contact
// between bodies of two owners has a body touching two parts), so it is never larger.
void scheduleCheck(const std::string& name, const cd::SavedProblem& pb)
{
	// {schedule, slabs, columns per slab}
	for (const auto& [schedule, slabs, across] : std::vector<std::tuple<int, int, int>> {
	             { 4, pb.params.slabs, 1 }, { 5, 2, 1 }, { 5, 4, 1 }, { 5, 8, 1 }, { 5, 64, 1 }, { 5, 2, 2 }, { 5, 4, 4 }, { 5, 8, 8 }, { 5, 2, 32 } })
		for (bool owned : { false, true }) {
			if (owned && schedule != 5) continue;
			cd::Params p  = pb.params;
			p.schedule    = schedule;
			p.slabs       = slabs;
			p.slabsAcross = across;
			p.slabsOwnBodies = owned;
			p.maxIter     = 1;
			p.parallelMinContacts = 0; // keep the schedule's own parallel flags
			cd::Solver s;
			pb.load(s);
			s.assemble(p);
			s.solve(p);
			const cd::Schedule& o  = s.schedule();
			const long          nc = long(s.contacts.size());
			bool                ok = !o.bounds.empty() && o.bounds.front() == 0 && o.bounds.back() == nc;
			for (size_t i = 0; i + 1 < o.bounds.size(); ++i)
				ok = ok && o.bounds[i] <= o.bounds[i + 1];
			int conflicts = 0, parallelStages = 0;
			for (const auto& st : o.stages) {
				ok = ok && st.begin <= st.end && st.end <= o.ranges();
				if (!st.parallel) continue;
				++parallelStages;
				std::map<int, int> owner; // dynamic body -> range
				for (int i = st.begin; i < st.end; ++i)
					for (long k = o.bounds[i]; k < o.bounds[i + 1]; ++k)
						for (int b : { s.contacts.info[k].b1, s.contacts.info[k].b2 }) {
							if (!s.records[b].dynamic) continue;
							const auto it = owner.find(b);
							if (it == owner.end()) owner[b] = i;
							else if (it->second != i) ++conflicts;
						}
			}
			ok = ok && (nc < 1000 || slabs * across > 4 || parallelStages > 0); // a step this large in a few parts has stages worth threads: the check is not empty
			const std::string what = name + " [schedule " + std::to_string(p.schedule) + (p.schedule == 5 ? ", " + std::to_string(p.slabs) + " slabs x " + std::to_string(p.slabsAcross) : "") + (owned ? ", bodies owned" : "") + "]";
			check(ok && conflicts == 0, what + ": the ranges cover the contacts and those of a parallel stage share no dynamic body (" + std::to_string(conflicts) + " shared)");
			if (!owned) continue;
			cd::Params touched     = p;
			touched.slabsOwnBodies = false;
			cd::Solver t;
			pb.load(t);
			t.assemble(touched);
			t.solve(touched);
			check(o.nInterface <= t.schedule().nInterface,
			      what + ": the interface is no larger than with the parts touched (" + std::to_string(o.nInterface) + " against " + std::to_string(t.schedule().nInterface) + " contacts)");
		}
}

void roundTrip(const std::string& name, const std::string& path, const cd::SavedProblem& pb)
{
	std::ifstream f(path);
	std::string   original((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
	cd::Solver    s;
	pb.load(s);
	std::ostringstream o;
	cd::writeProblem(o, s, pb.params);
	check(original.compare(0, o.str().size(), o.str()) == 0, name + ": written back, the same text");
	// the optional trailing fields, each alone and after the others
	for (const auto& [across, momentum, owned] : std::vector<std::tuple<int, bool, bool>> { { 1, true, false }, { 3, false, false }, { 3, true, false }, { 1, false, true }, { 2, true, true } }) {
		cd::Params p         = pb.params;
		p.slabsAcross        = across;
		p.correctionMomentum = momentum;
		p.slabsOwnBodies     = owned;
		std::stringstream io;
		cd::writeProblem(io, s, p);
		const cd::SavedProblem back = cd::readProblem(io);
		check(back.params.slabsAcross == across && back.params.correctionMomentum == momentum && back.params.slabsOwnBodies == owned,
		      name + ": slabsAcross " + std::to_string(across) + ", correctionMomentum " + std::to_string(momentum) + " and slabsOwnBodies " + std::to_string(owned) + " read back");
	}
}

void badInput()
{
	const char* cases[] = { "", "cdproblem 2\n", "cdproblem 1\nparams 1e-4 0 0 1\n",
		                    "cdproblem 1\nparams 1e-4 0 0 1 1e-6 100 1 1 1 2 1 1 1e-6 200\nbodies 1\nbody 0 1 1 1 0 0 0 0 0 0 1 1 1 1 0 0 0 1 0 0 0 1 0 0 0 0 0 0\ncontacts 1\ncontact 0 3 0.4 0\n" };
	const char* expect[] = { "ends before the header", "unknown format version", "line 2", "line 6" };
	for (int i = 0; i < 4; ++i) {
		std::istringstream in(cases[i]);
		std::string        msg;
		try {
			cd::readProblem(in);
		} catch (const std::runtime_error& e) {
			msg = e.what();
		}
		check(msg.find(expect[i]) != std::string::npos, std::string("bad problem file ") + std::to_string(i) + " refused naming \"" + expect[i] + "\" (got \"" + msg + "\")");
	}
}

} // namespace

void cdtest::solverTests(const std::string& dataDir)
{
	badInput();
	std::vector<std::string> files;
	if (DIR* d = opendir(dataDir.c_str())) {
		while (dirent* ent = readdir(d)) {
			const std::string n = ent->d_name;
			if (n.size() > 4 && n.compare(n.size() - 4, 4, ".cdp") == 0) files.push_back(n);
		}
		closedir(d);
	}
	std::sort(files.begin(), files.end());
	check(files.size() >= 5, "problem files found in " + dataDir + " (" + std::to_string(files.size()) + ")");
	int corrected = 0;
	for (const std::string& n : files) {
		const std::string  path = dataDir + "/" + n;
		cd::SavedProblem   pb   = cd::readProblemFile(path);
		const Expectations e    = parseExtra(pb.extra);
		reproduceEngine(n, pb, e);
		optionGrid(n, pb, e);
		corrected += correctionCheck(n, pb) ? 1 : 0;
		threadsCheck(n, pb);
		worklistCheck(n, pb, e);
		traceCheck(n, pb);
		scheduleCheck(n, pb);
		roundTrip(n, path, pb);
	}
	check(corrected >= 1, "the position correction was checked on " + std::to_string(corrected) + " of the problem files (some step must need one)");
}
