// Contact Dynamics solver core: assembly, Gauss–Seidel solve and position correction (see
// Solver.hpp for the stages, Problem.hpp for the data, LocalSolver.hpp for the contact law).
#include "Solver.hpp"
#include "LocalSolver.hpp"

#include <limits>
#include <stdexcept>
#include <string>

namespace yade {
namespace cd {

// The sweep's innermost helpers are member functions: in a -fPIC shared library GCC calls
// interposable functions through the PLT instead of inlining them, which made the sweep 14%
// slower (measured with perf and solver_bench.py). Force them inline.
#define CD_HOT inline __attribute__((always_inline))

	namespace {
		// Cross-product matrix [c]x, so that [c]x p = c × p.
		Matrix3r skew(const Vector3r& c)
		{
			Matrix3r m;
			m << 0, -c[2], c[1], c[2], 0, -c[0], -c[1], c[0], 0;
			return m;
		}
		std::string pairName(int id1, int id2) { return "(#" + std::to_string(id1) + ", #" + std::to_string(id2) + ")"; }

		// M v and Mᵀ v written out, for the general kernel and the correction: GCC leaves Eigen's
		// 3×3 products there as calls (perf, on a pile of dimers: 13 % of the solve in them). The
		// sums are in Eigen's order, x0 + (x1 + x2): the same results, bit for bit (the core tier's
		// saved steps).
		CD_HOT Vector3r mul(const Matrix3r& M, const Vector3r& v)
		{
			return Vector3r(M(0, 0) * v[0] + (M(0, 1) * v[1] + M(0, 2) * v[2]), M(1, 0) * v[0] + (M(1, 1) * v[1] + M(1, 2) * v[2]),
			                M(2, 0) * v[0] + (M(2, 1) * v[1] + M(2, 2) * v[2]));
		}
		CD_HOT Vector3r mulT(const Matrix3r& M, const Vector3r& v)
		{
			return Vector3r(M(0, 0) * v[0] + (M(1, 0) * v[1] + M(2, 0) * v[2]), M(0, 1) * v[0] + (M(1, 1) * v[1] + M(2, 1) * v[2]),
			                M(0, 2) * v[0] + (M(1, 2) * v[1] + M(2, 2) * v[2]));
		}
	}

	// ------------------------------------------------------------------------- stage 5: assembly

	// Per contact, W = F (K1 + K2) Fᵀ with K_b = diag(1/m_b) − [c_b]x I_b⁻¹ [c_b]x, the
	// start-of-step local velocity U_i, and the law's scaling A and offset s:
	//   open   (g_m > 0): A = 1, s = (2 g_m/h, 0, 0): the end-of-step gap g_m + h/2 U_N stays ≥ 0;
	//   closed (g_m ≤ 0): Moreau's restitution mean, A = diag(1/(1+e)), s = e∘U_i (a contact that
	//                     landed last step uses its landing velocity instead of U_i).
	void Solver::assemble(const Params& p)
	{
		const Real h  = p.h;
		const long nc = long(contacts.size());
		qShare.resize(nc); // each contact's share of ‖q‖², summed below in a fixed order
#pragma omp parallel for schedule(static) if (nc >= 2048)
		for (long k = 0; k < nc; ++k) { // contacts are independent here: any thread count gives the same blocks
			ContactInfo&      c  = contacts.info[k];
			const Body&       b1 = bodies[c.b1];
			const Body&       b2 = bodies[c.b2];
			const BodyRecord& r1 = records[c.b1];
			const BodyRecord& r2 = records[c.b2];
			const Matrix3r    S1 = skew(c.c1), S2 = skew(c.c2);
			const Matrix3r    K  = Matrix3r(b1.invM.asDiagonal()) - S1 * b1.invI * S1 + Matrix3r(b2.invM.asDiagonal()) - S2 * b2.invI * S2;
			c.W                  = c.frame * K * c.frame.transpose();
			qShare[k]            = 0;
			if (!(c.W(0, 0) > 0)) continue; // reported below, outside the parallel loop
			c.Ui = c.frame * ((r2.vi + r2.wi.cross(c.c2)) - (r1.vi + r1.wi.cross(c.c1)));
			if (c.shifted) { // a periodic image moves with the cell: its velocity enters every U
				c.Us = c.frame * c.shift;
				c.Ui += c.Us;
			}
			if (c.gapM > 0) {
				c.A = Vector3r::Ones();
				c.s = Vector3r(2 * c.gapM / h, 0, 0);
			} else {
				const Vector3r Ui = (c.approach != Vector3r::Zero()) ? Vector3r(c.frame * c.approach) : c.Ui;
				c.A               = Vector3r(1 / (1 + c.en), 1 / (1 + c.et), 1 / (1 + c.et));
				c.s               = Vector3r(c.en * Ui[0], c.et * Ui[1], c.et * Ui[2]);
			}
			contacts.state[k].r = c.frame * c.warmStart; // warm start, re-expressed in the new frame
			buildSphereRow(k, p.sphereFastPath);
			// residual scale: free local velocities of the contacts that would close without an
			// impulse (q_N < 0); far gap contacts, whose offsets 2 g_m/h are large, do not dilute it
			const Vector3r q = c.A.cwiseProduct(localVelocity(k) + c.s);
			if (q[0] < 0) qShare[k] = q.squaredNorm();
		}
		qNorm = 0;
		contacts.general.clear();
		for (long k = 0; k < nc; ++k) {
			const ContactInfo& c = contacts.info[k];
			if (!(c.W(0, 0) > 0))
				throw std::invalid_argument("contact " + pairName(c.b1, c.b2) + " joins two bodies that cannot move: make one of them dynamic or remove the contact.");
			qNorm += qShare[k];
			if (contacts.state[k].kernel >= 0) contacts.state[k].kernel = int(contacts.general.size()), contacts.general.emplace_back();
		}
		qNorm           = math::sqrt(qNorm);
		const long ng   = long(contacts.general.size());
		if (ng == 0) return;
#pragma omp parallel for schedule(static) if (ng >= 2048)
		for (long k = 0; k < nc; ++k) {
			if (contacts.state[k].kernel < 0) continue;
			const ContactInfo& c = contacts.info[k];
			GeneralRow&        g = contacts.general[contacts.state[k].kernel];
			g.Wlaw               = c.A.asDiagonal() * c.W;
			g.WlawInv            = g.Wlaw.inverse();
		}
	}

	// The sphere kernel's row of contact k when its geometry and bodies allow (see SphereRow);
	// otherwise the contact is marked for the general kernel (kernel[k] = 0 until numbered).
	void Solver::buildSphereRow(long k, bool allowed)
	{
		const ContactInfo& c = contacts.info[k];
		contacts.state[k].kernel   = 0;
		if (!allowed) return;
		Real lever[2], invM[2], invI[2];
		for (int side = 0; side < 2; ++side) {
			const int         id = side ? c.b2 : c.b1;
			const BodyRecord& br = records[id];
			const Vector3r&   cb = side ? c.c2 : c.c1;
			const Vector3r    n  = c.frame.row(0);
			lever[side]          = cb.dot(n);
			if (br.dynamic) {
				if (br.isoInvM < 0 || (cb - lever[side] * n).squaredNorm() > 1e-20 * cb.squaredNorm()) return;
				invM[side] = br.isoInvM;
				invI[side] = br.isoInvI;
			} else {
				if (bodies[id].w != Vector3r::Zero()) return; // a rotating obstacle: general kernel
				invM[side] = invI[side] = 0;
			}
		}
		SphereRow& h    = contacts.sphere[k];
		contacts.state[k].kernel = -1;
		h.n                = c.frame.row(0);
		h.t1               = c.frame.row(1);
		h.t2               = c.frame.row(2);
		h.l1 = lever[0], h.l2 = lever[1];
		h.m1 = invM[0], h.m2 = invM[1];
		h.k1 = invI[0] * lever[0], h.k2 = invI[1] * lever[1];
		const Real wn = h.m1 + h.m2, wt = wn + h.l1 * h.k1 + h.l2 * h.k2;
		h.Wd          = c.A.cwiseProduct(Vector3r(wn, wt, wt));
		h.A           = c.A;
		h.bias        = c.shifted ? Vector3r(c.A.cwiseProduct(c.s + c.Us)) : Vector3r(c.A.cwiseProduct(c.s));
		h.wnn         = wn;
		h.b1 = c.b1, h.b2 = c.b2;
	}

	Vector3r Solver::localVelocity(long k) const
	{
		const ContactInfo& c  = contacts.info[k];
		const Body&        b1 = bodies[c.b1];
		const Body&        b2 = bodies[c.b2];
		const Vector3r     U  = mul(c.frame, (b2.v + b2.w.cross(c.c2)) - (b1.v + b1.w.cross(c.c1)));
		return c.shifted ? Vector3r(U + c.Us) : U;
	}

	// ------------------------------------------------------------------------- the two kernels

	// Local velocity U of a sphere-kernel contact. With c_b = l_b n the rotation terms are
	// l_b (w_b × n), whose local components are (0, w_b·t2, −w_b·t1).
	CD_HOT Vector3r Solver::sphereVelocity(const SphereRow& c) const
	{
		const Body&    B1 = bodies[c.b1];
		const Body&    B2 = bodies[c.b2];
		const Vector3r dv = B2.v - B1.v;
		const Vector3r om = c.l2 * B2.w - c.l1 * B1.w;
		return Vector3r(c.n.dot(dv), c.t1.dot(dv) + om.dot(c.t2), c.t2.dot(dv) - om.dot(c.t1));
	}

	// The impulse change dr (local frame) applied to both bodies; its moment about a centre is
	// l_b (n × P) = l_b (dr_1 t2 − dr_2 t1). Obstacles are never written (parallel stages share them).
	CD_HOT void Solver::applySphereImpulse(const SphereRow& c, const Vector3r& dr)
	{
		const Vector3r P = dr[0] * c.n + dr[1] * c.t1 + dr[2] * c.t2;
		const Vector3r x = dr[1] * c.t2 - dr[2] * c.t1;
		if (c.m2 > 0) {
			Body& B2 = bodies[c.b2];
			B2.v += c.m2 * P;
			B2.w += c.k2 * x;
		}
		if (c.m1 > 0) {
			Body& B1 = bodies[c.b1];
			B1.v -= c.m1 * P;
			B1.w -= c.k1 * x;
		}
	}

	// The impulse change dr (local frame) of any contact applied to both bodies. Out of line, for
	// the reason given at updateGeneral: its callers' loops are the sphere kernel's.
	__attribute__((noinline)) void Solver::applyImpulse(const ContactInfo& c, const Vector3r& dr)
	{
		const Vector3r P  = mulT(c.frame, dr); // on body 2; −P on body 1
		Body&          b1 = bodies[c.b1];
		Body&          b2 = bodies[c.b2];
		if (records[c.b2].dynamic) {
			b2.v += b2.invM.cwiseProduct(P);
			b2.w += mul(b2.invI, c.c2.cross(P));
		}
		if (records[c.b1].dynamic) {
			b1.v -= b1.invM.cwiseProduct(P);
			b1.w -= mul(b1.invI, c.c1.cross(P));
		}
	}

	// One Gauss–Seidel update of contact k: its local velocity without its own impulse,
	// b = U − W r, the exact local solve of Ũ = A(W r + b + s), the change applied to both bodies
	// at once. Returns (W_NN |Δr|)² and tells whether the status changed. Relaxed: the
	// over-relaxed update r ← P_C(r + ω(r_local − r)) for closed contacts (a separate instance,
	// so that the default kernel carries no trace of it).
	template <bool Relaxed> CD_HOT Real Solver::updateContact(long k, Real omega, bool& changed)
	{
		ContactState& st = contacts.state[k];
		if (st.kernel >= 0) return updateGeneral<Relaxed>(k, omega, changed);
		const SphereRow& c   = contacts.sphere[k];
		const int        before = st.status;
		const Vector3r   b      = c.A.cwiseProduct(sphereVelocity(c)) - c.Wd.cwiseProduct(st.r) + c.bias;
		Vector3r         rNew;
		st.status = int(solveLocalDiagonal(c.Wd, b, st.mu, rNew));
		if (Relaxed && omega != 1 && st.status != int(ContactStatus::Open)) rNew = projectOnCone(st.r + omega * (rNew - st.r), st.mu);
		const Vector3r dr = rNew - st.r;
		applySphereImpulse(c, dr);
		st.r    = rNew;
		changed = st.status != before;
		return dr.squaredNorm() * c.wnn * c.wnn;
	}

	// The general kernel's update, out of line: inlined into the sweep loop it would exhaust the
	// inliner's budget there and leave the sphere kernel's small Eigen helpers as calls (measured:
	// the sphere kernel 25–35% slower).
	template <bool Relaxed> __attribute__((noinline)) Real Solver::updateGeneral(long k, Real omega, bool& changed)
	{
		ContactState& st     = contacts.state[k];
		const int          before = st.status;
		const ContactInfo& c      = contacts.info[k];
		const GeneralRow&  g      = contacts.general[st.kernel];
		const Vector3r     U      = localVelocity(k);
		const Vector3r     b      = c.A.cwiseProduct(U - mul(c.W, st.r) + c.s);
		Vector3r           rNew   = st.r;
		st.status                 = int(solveLocal(g.Wlaw, g.WlawInv, b, st.mu, rNew));
		if (Relaxed && omega != 1 && st.status != int(ContactStatus::Open)) rNew = projectOnCone(st.r + omega * (rNew - st.r), st.mu);
		const Vector3r dr = rNew - st.r;
		applyImpulse(c, dr);
		st.r    = rNew;
		changed = st.status != before;
		return dr.squaredNorm() * c.W(0, 0) * c.W(0, 0);
	}

	// Contacts [begin, end) updated in turn: returns Σ(W_NN|Δr|)², adds status changes to nChanged
	// and the updates made to updates. Mode (SweepMode): Partial skips a contact unless one of its
	// bodies was stamped in the sweep before or earlier in this one (an update of a contact whose
	// bodies did not move since its last update would give back its own impulse, up to the
	// threshold); Marking and Partial stamp the dynamic bodies of a significant update (a parallel
	// stage's ranges share none, so the stamps are the same for any thread count). PerContact:
	// every contact's change is kept for schedules that sum contact by contact, and for the trace.
	template <bool Relaxed, int Mode, bool PerContact> CD_HOT Real Solver::sweepRange(long begin, long end, Real omega, int& nChanged, long& updates)
	{
		Real      change = 0;
		const int t      = sweepIndex;
		const int nb     = int(bodies.size());
		for (long k = begin; k < end; ++k) {
			if constexpr (Mode == Partial) {
				if (stamp[stampSlot[2 * k]] < t - 1 && stamp[stampSlot[2 * k + 1]] < t - 1) {
					if constexpr (PerContact) contactChange[k] = 0;
					continue;
				}
				++updates;
			}
			bool       changed;
			const Real c = updateContact<Relaxed>(k, omega, changed);
			if constexpr (PerContact) contactChange[k] = c;
			change += c;
			nChanged += changed;
			if constexpr (Mode != Full) {
				if (c > workThreshold2) {
					if (stampSlot[2 * k] != nb) stamp[stampSlot[2 * k]] = t;
					if (stampSlot[2 * k + 1] != nb) stamp[stampSlot[2 * k + 1]] = t;
				}
			}
		}
		if constexpr (Mode != Partial) updates += end - begin;
		return change;
	}

	// One sweep in the schedule's order. Every range's sum (or every contact's change, for
	// schedules that sum contact by contact) is stored and the sums added in order afterwards:
	// the result, bit for bit, does not depend on the number of threads (nor on the trace: a
	// range's sum is the same whether or not its contacts' changes are also stored).
	template <bool Relaxed, int Mode, bool PerContact> Real Solver::sweepAll(Real omega, int& nChanged, long& updates)
	{
		order.run([&](int i, long begin, long end) {
			int  n = 0;
			long u = 0;
			rangeChange[i]  = sweepRange<Relaxed, Mode, PerContact>(begin, end, omega, n, u);
			rangeStatus[i]  = n;
			rangeUpdates[i] = u;
		});
		Real change = 0;
		nChanged    = 0;
		updates     = 0;
		for (int i = 0; i < order.ranges(); ++i) {
			nChanged += rangeStatus[i];
			updates += rangeUpdates[i];
		}
		if (order.sumPerContact)
			for (size_t k = 0; k < contacts.size(); ++k)
				change += contactChange[k];
		else
			for (int i = 0; i < order.ranges(); ++i)
				change += rangeChange[i];
		return change;
	}

	template <bool Relaxed> Real Solver::sweep(Real omega, int mode, bool perContact, int& nChanged, long& updates)
	{
		switch (2 * mode + int(perContact)) {
			case 2 * Full: return sweepAll<Relaxed, Full, false>(omega, nChanged, updates);
			case 2 * Full + 1: return sweepAll<Relaxed, Full, true>(omega, nChanged, updates);
			case 2 * Marking: return sweepAll<Relaxed, Marking, false>(omega, nChanged, updates);
			case 2 * Marking + 1: return sweepAll<Relaxed, Marking, true>(omega, nChanged, updates);
			case 2 * Partial: return sweepAll<Relaxed, Partial, false>(omega, nChanged, updates);
			default: return sweepAll<Relaxed, Partial, true>(omega, nChanged, updates);
		}
	}

	// The worklist's state for one solve: every body unstamped, each contact's two stamp slots
	// (in the schedule's order), and the threshold (W_NN|Δr|)² of a significant update.
	void Solver::startWorklist(const Params& p, Real scale)
	{
		const long nc = long(contacts.size());
		const int  nb = int(bodies.size());
		stamp.assign(nb + 1, std::numeric_limits<int>::min() / 2);
		stampSlot.resize(2 * nc);
		for (long k = 0; k < nc; ++k) {
			const ContactInfo& c = contacts.info[k];
			stampSlot[2 * k]     = records[c.b1].dynamic ? c.b1 : nb;
			stampSlot[2 * k + 1] = records[c.b2].dynamic ? c.b2 : nb;
		}
		const Real theta = p.worklistThreshold * p.tolerance * scale / math::sqrt(Real(nc));
		workThreshold2   = theta * theta;
	}

	// ------------------------------------------------------------------------- stage 6: the solve

	// Relative residual: sqrt(Σ|e_α|²)/‖q‖, e_α the natural-map residual in velocity units
	// (ρ_α = 1/W̃_NN,α for the law's own block A·W); counts sticking and sliding contacts.
	// The contacts' terms are evaluated on the sweep's threads (they only read), then summed on
	// the calling thread in contact order: the same sum, bit for bit, on any thread count (on one
	// thread, checks were 10–16 % of a fed full-size step's solve on two: docs/performance.md).
	Real Solver::residual(SolveStats& stats)
	{
		const long nc = long(contacts.size());
		residual2.resize(size_t(nc));
#pragma omp parallel for schedule(static) if (sweepThreads)
		for (long k = 0; k < nc; ++k)
			residual2[size_t(k)] = contactResidual2(k);
		Real sum        = 0;
		stats.nSticking = stats.nSliding = 0;
		for (long k = 0; k < nc; ++k) {
			sum += residual2[size_t(k)];
			if (contacts.state[k].status == int(ContactStatus::Sticking)) ++stats.nSticking;
			if (contacts.state[k].status == int(ContactStatus::Sliding)) ++stats.nSliding;
		}
		const Real scale = qNorm > 0 ? qNorm : Real(1);
		return math::sqrt(sum) / scale;
	}

	// |e_k|², contact k's natural-map residual in velocity units, squared.
	Real Solver::contactResidual2(long k) const
	{
		Vector3r Ulaw;
		Real     rho;
		if (contacts.state[k].kernel < 0) {
			const SphereRow& c = contacts.sphere[k];
			Ulaw               = c.A.cwiseProduct(sphereVelocity(c)) + c.bias;
			rho                = 1 / c.Wd[0];
		} else {
			const ContactInfo& c = contacts.info[k];
			Ulaw                 = c.A.cwiseProduct(localVelocity(k) + c.s);
			rho                  = 1 / contacts.general[contacts.state[k].kernel].Wlaw(0, 0);
		}
		return naturalMapResidual(contacts.state[k].r, Ulaw, contacts.state[k].mu, rho).squaredNorm();
	}

	// The trace of the sweep just made (Params::traceContacts): every contact's change, from the
	// per-contact changes the sweep kept, and its residual now.
	void Solver::recordTrace(SolveStats& stats) const
	{
		const size_t nc = contacts.size(), at = stats.traceChange.size();
		stats.traceChange.resize(at + nc);
		stats.traceResidual.resize(at + nc);
		for (size_t k = 0; k < nc; ++k) {
			stats.traceChange[at + k]   = float(math::sqrt(contactChange[k]));
			stats.traceResidual[at + k] = float(math::sqrt(contactResidual2(long(k))));
		}
	}

	// Nonlinear Gauss–Seidel over contacts, accelerated by Nesterov's momentum with adaptive
	// restart. Stops when the exact residual is below the tolerance, or after maxIter sweeps.
	SolveStats Solver::solve(const Params& p)
	{
		SolveStats stats;
		for (size_t k = 0; k < contacts.size(); ++k)
			applyImpulse(contacts.info[k], contacts.state[k].r); // warm start, in height order
		if (contacts.size() == 0) {
			order.build(Schedule::Height, contacts, records, p.slabs, p.slabsAcross, p.slabsOwnBodies, p.up);
			return stats;
		}
		stats.converged  = false;
		const Real scale = qNorm > 0 ? qNorm : Real(1);
		Real       omega = p.relaxation, bestChange = std::numeric_limits<Real>::infinity();
		int        stalled = 0;
		order.build(p.schedule, contacts, records, p.slabs, p.slabsAcross, p.slabsOwnBodies, p.up);
		// A sweep opens a parallel region per stage: on small problems two threads gain nothing
		// and, when another process takes a core, their spinning barriers cost 15x
		// (docs/performance.md, "Two threads beside another process").
		sweepThreads = long(contacts.size()) >= p.parallelMinContacts;
		if (!sweepThreads) order.serial();
		stats.nColours   = order.nColours;
		stats.nInterface = order.nInterface;
		stats.nWide    = order.nWide;
		rangeChange.assign(order.ranges(), 0);
		rangeStatus.assign(order.ranges(), 0);
		rangeUpdates.assign(order.ranges(), 0);
		const bool perContact = order.sumPerContact || p.traceContacts;
		if (perContact) contactChange.assign(contacts.size(), 0);
		if (p.bodiesInSweepOrder) renumberBodies();
		if (p.worklist) startWorklist(p, scale);
		if (p.momentum) startMomentum();
		// Momentum restarts when a sweep changes the velocities more than restartGrowth times the
		// sweep before. 1.2 rather than 1 lets momentum ride through small bumps (measured on pile
		// steps: 109 and 178 sweeps against 313 and 234 with 1); the stall guard below falls back to 1.
		Real       tNesterov = 1, lastChange = std::numeric_limits<Real>::infinity(), restartGrowth = 1.2;
		const bool relaxed   = p.relaxation != 1;
		bool       fullNext  = true; // worklist: the next sweep visits every contact
		for (int it = 1; it <= p.maxIter; ++it) {
			sweepIndex        = it;
			const bool called = p.worklist && fullNext && it > 1; // a full sweep after a quiet partial one
			const bool full   = !p.worklist || fullNext || it <= p.worklistFullSweeps;
			const int  mode = !p.worklist ? Full : full ? Marking : Partial;
			long       updates;
			// Σ (W_NN |Δr|)²: the velocity changes this sweep made
			const Real change = relaxed ? sweep<true>(omega, mode, perContact, stats.nStatusChanges, updates)
			                            : sweep<false>(omega, mode, perContact, stats.nStatusChanges, updates);
			stats.iterations  = it;
			stats.contactUpdates += updates;
			stats.fullSweeps += full;
			if (p.traceContacts) recordTrace(stats);
			// The exact residual costs about a sweep: evaluate it only once the sweep's own changes
			// are below the tolerance (a converged state barely changes), or when asked to record.
			// With the worklist a quiet partial sweep only calls for a full sweep: the contacts it
			// skipped may have drifted (each by less than the threshold), so only a full sweep may
			// be followed by the test that ends the solve.
			const bool quiet = math::sqrt(change) <= p.tolerance * scale;
			fullNext         = !full && quiet;
			// Over-relaxation and a lenient momentum restart are not safe with friction: once the
			// sweeps stop contracting (the smallest change so far not improved by 1% for p.stallWindow sweeps, 50),
			// finish the step with ω = 1 and momentum restarted at every growth.
			if (change < 0.99 * bestChange) {
				bestChange = change;
				stalled    = 0;
			} else if (++stalled >= p.stallWindow && (omega != 1 || restartGrowth != 1)) {
				omega         = 1;
				restartGrowth = 1;
				tNesterov     = 1;
			}
			if (it == p.maxIter || (((quiet && full) || p.recordResidual) && it % p.checkEvery == 0)) {
				stats.residual = residual(stats);
				++stats.residualChecks;
				if (p.recordResidual) stats.residualHistory.push_back(stats.residual);
				if (stats.residual <= p.tolerance) {
					stats.converged = true;
					break;
				}
			}
			// A full sweep called by a quiet partial one that did not end the solve: what is left
			// is spread over contacts whose updates are each below the threshold, which partial
			// sweeps never visit; halve the threshold so that they take part.
			if (called && it > p.worklistFullSweeps) workThreshold2 *= 0.25;
			if (p.momentum && it < p.maxIter) {
				// adaptive restart: a sweep that changed clearly more than the one before ends the momentum
				if (change > restartGrowth * lastChange) tNesterov = 1;
				lastChange      = change;
				const Real next = (1 + math::sqrt(1 + 4 * tNesterov * tNesterov)) / 2;
				extrapolate((tNesterov - 1) / next);
				tNesterov = next;
			}
		}
		restoreBodyIds();
		return stats;
	}

	// Nesterov momentum over whole sweeps. The velocities are affine in the impulses,
	// V(r) = u_free + M⁻¹ H r, so the start of the next sweep, y = x_k + β (x_k − x_{k−1}), has
	// velocities V(x_k) + β (V(x_k) − V(x_{k−1})): one pass over bodies. Where y leaves a contact's
	// cone it is projected, and the projection's impulse is applied to the two bodies.
	void Solver::startMomentum()
	{
		rPrev.resize(contacts.size());
		for (size_t k = 0; k < contacts.size(); ++k)
			rPrev[k] = contacts.state[k].r;
		vPrev.resize(bodies.size());
		wPrev.resize(bodies.size());
		for (size_t b = 0; b < bodies.size(); ++b) {
			vPrev[b] = bodies[b].v;
			wPrev[b] = bodies[b].w;
		}
	}

	void Solver::extrapolate(Real beta)
	{
		const long nb = long(bodies.size());
#pragma omp parallel for schedule(static) if (sweepThreads && nb >= 4096)
		for (long b = 0; b < nb; ++b) { // obstacles: v = vPrev (never written), unchanged
			Body&          B = bodies[b];
			const Vector3r v = B.v, w = B.w;
			B.v += beta * (v - vPrev[b]);
			B.w += beta * (w - wPrev[b]);
			vPrev[b] = v;
			wPrev[b] = w;
		}
		order.run([&](int, long begin, long end) { extrapolateRange(begin, end, beta); });
	}

	// The contact part of the extrapolation for contacts [begin, end): y = x + β(x − x_prev); where
	// y leaves the cone, its projection, whose impulse is applied to the two bodies.
	void Solver::extrapolateRange(long begin, long end, Real beta)
	{
		for (long k = begin; k < end; ++k) {
			Vector3r&      r = contacts.state[k].r;
			const Vector3r x = r;
			if (x == rPrev[k]) continue; // unchanged (open contacts mostly): y = x
			if (beta == 0) {             // a restart: y = x, already in its cone
				rPrev[k] = x;
				continue;
			}
			const Vector3r y  = x + beta * (x - rPrev[k]);
			const Real     mu = contacts.state[k].mu;
			rPrev[k]          = x;
			r                 = y;
			if (y[0] >= 0 && y[1] * y[1] + y[2] * y[2] <= mu * mu * y[0] * y[0]) continue; // inside the cone
			r = projectOnCone(y, mu);
			if (contacts.state[k].kernel < 0) applySphereImpulse(contacts.sphere[k], r - y);
			else
				applyImpulse(contacts.info[k], r - y);
		}
	}

	// ------------------------------------------------------------------------- stage 7: correction

	// Pseudo-velocities during the correction: translations in pseudoV, rotations in the records
	// (only general rows make them).
	Vector3r Solver::localPseudoVelocity(const ContactInfo& c) const
	{
		return mul(c.frame, (pseudoV[c.b2] + records[c.b2].pw.cross(c.c2)) - (pseudoV[c.b1] + records[c.b1].pw.cross(c.c1)));
	}

	void Solver::applyPseudoImpulse(const ContactInfo& c, Real dP)
	{
		const Vector3r P = c.frame.row(0).transpose() * dP;
		if (records[c.b2].dynamic) {
			pseudoV[c.b2] += bodies[c.b2].invM.cwiseProduct(P);
			records[c.b2].pw += mul(bodies[c.b2].invI, c.c2.cross(P));
		}
		if (records[c.b1].dynamic) {
			pseudoV[c.b1] -= bodies[c.b1].invM.cwiseProduct(P);
			records[c.b1].pw -= mul(bodies[c.b1].invI, c.c1.cross(P));
		}
	}

	// One correction sweep over rows [begin, end), forwards or backwards: returns the largest
	// overlap beyond its allowance met (relative) before each row's update; with complementarity,
	// also the largest separation of a row that still pushes (P > 0 with the gap open beyond the
	// allowance: min(P/gain, −v)), which an extrapolated start can create.
	Real Solver::correctionRange(long begin, long end, bool forward, bool complementarity)
	{
		Real worst = 0;
		for (long j = begin; j < end; ++j) {
			const long     k   = forward ? j : end - 1 - (j - begin);
			CorrectionRow& row = corrections[k];
			// normal pseudo-velocity; for a sphere row rotations never enter it (the lever arm is
			// along n) and a normal pseudo-impulse never makes them
			const Real un   = row.sphere ? row.n.dot(pseudoV[row.b2] - pseudoV[row.b1]) : localPseudoVelocity(contacts.info[k])[0];
			const Real v    = row.overlap - row.lag * un; // > 0: overlap beyond the allowance
			worst           = math::max(worst, v);
			if (complementarity && row.P > 0 && v < 0) worst = math::max(worst, math::min(row.P / row.gain, -v));
			const Real Pnew = math::max(Real(0), row.P + row.gain * v);
			const Real dP   = Pnew - row.P;
			if (dP != 0) {
				if (row.sphere) {
					if (row.m2 > 0) pseudoV[row.b2] += row.m2 * dP * row.n;
					if (row.m1 > 0) pseudoV[row.b1] -= row.m1 * dP * row.n;
				} else
					applyPseudoImpulse(contacts.info[k], dP);
			}
			row.P = Pnew;
		}
		return worst;
	}

	// Nesterov's extrapolation of the correction, P_y = P + β(P − P_prev) ≥ 0: the pseudo-velocities
	// are linear in P, so one pass over bodies extrapolates them; a row whose P_y would be negative
	// is set to 0 and its bodies get the difference.
	void Solver::extrapolateCorrection(Real beta)
	{
		const long nb = long(bodies.size());
#pragma omp parallel for schedule(static) if (sweepThreads && nb >= 4096)
		for (long b = 0; b < nb; ++b) {
			const Vector3r v = pseudoV[b], w = records[b].pw;
			pseudoV[b] += beta * (v - pvPrev[b]);
			records[b].pw += beta * (w - pwPrev[b]);
			pvPrev[b] = v;
			pwPrev[b] = w;
		}
		order.run([&](int, long begin, long end) {
			for (long k = begin; k < end; ++k) {
				CorrectionRow& row = corrections[k];
				const Real     P   = row.P;
				if (P == pPrev[k]) continue;
				const Real y = P + beta * (P - pPrev[k]);
				pPrev[k]     = P;
				row.P        = y;
				if (y >= 0) continue;
				row.P = 0;
				if (row.sphere) {
					if (row.m2 > 0) pseudoV[row.b2] -= row.m2 * y * row.n;
					if (row.m1 > 0) pseudoV[row.b1] += row.m1 * y * row.n;
				} else
					applyPseudoImpulse(contacts.info[k], -y);
			}
		});
	}

	// The end-of-step gap is g_f = g_m + h/2 (U_f,N + Ũ_N), Ũ from normal pseudo-impulses P ≥ 0
	// that move positions but never velocities. Target: g_f ≥ −a, a the contact's overlap
	// allowance. Such overlaps are kept, so a packing at rest stays exactly at rest; the overlap
	// that steps create (by the half-step predictor after a landing, or an unconverged solve) is
	// removed, over several steps if the correction stops at maxProjectionIter. Projected
	// Gauss–Seidel, frictionless, in the solve's schedule with alternating directions.
	CorrectionStats Solver::correct(const Params& p)
	{
		CorrectionStats stats;
		const Real      h  = p.h;
		const long      nc = long(contacts.size());
		corrections.resize(nc);
		for (long k = 0; k < nc; ++k) { // the velocity part of the end-of-step gap is fixed now
			const ContactInfo& c   = contacts.info[k];
			CorrectionRow&     row = corrections[k];
			row.overlap            = (-c.allowance - c.gapM - 0.5 * h * localVelocity(k)[0]) / c.refR;
			stats.maxOverlap       = math::max(stats.maxOverlap, row.overlap);
		}
		if (stats.maxOverlap <= p.positionTolerance) return stats;
		if (p.bodiesInSweepOrder) renumberBodies();
		for (long k = 0; k < nc; ++k) {
			const ContactInfo& c   = contacts.info[k];
			CorrectionRow&     row = corrections[k];
			row.lag                = 0.5 * h / c.refR;
			row.gain               = (2 / h) * c.refR / c.W(0, 0);
			row.P                  = 0;
			row.sphere             = contacts.state[k].kernel < 0;
			row.b1 = c.b1, row.b2 = c.b2;
			if (row.sphere) {
				const SphereRow& f = contacts.sphere[k];
				row.n = f.n, row.m1 = f.m1, row.m2 = f.m2;
			}
		}
		pseudoV.assign(bodies.size(), Vector3r::Zero());
		const bool momentum = p.correctionMomentum;
		if (momentum) {
			pPrev.assign(nc, 0);
			pvPrev.assign(bodies.size(), Vector3r::Zero());
			pwPrev.assign(bodies.size(), Vector3r::Zero());
		}
		std::vector<Real>& rangeWorst = rangeChange;
		Real               tNesterov = 1, lastWorst = std::numeric_limits<Real>::infinity();
		for (int it = 1; it <= p.maxProjectionIter; ++it) {
			// plain: alternating directions; with momentum always forwards (alternating breaks the
			// extrapolation: 186 against 48 sweeps on a fed 14 000-grain cone step)
			const bool forward = momentum || it % 2 == 1;
			auto       pass    = [&](int i, long begin, long end) { rangeWorst[i] = correctionRange(begin, end, forward, momentum); };
			if (forward) order.run(pass);
			else
				order.runBackwards(pass);
			Real worst = 0;
			for (int i = 0; i < order.ranges(); ++i)
				worst = math::max(worst, rangeWorst[i]);
			stats.iterations = it;
			if (worst <= p.positionTolerance) break;
			if (momentum && it < p.maxProjectionIter) { // as in the solve: restart when a sweep ends clearly worse than the one before
				if (worst > 1.2 * lastWorst) tNesterov = 1;
				lastWorst       = worst;
				const Real next = (1 + math::sqrt(1 + 4 * tNesterov * tNesterov)) / 2;
				extrapolateCorrection((tNesterov - 1) / next);
				tNesterov = next;
			}
		}
		for (size_t b = 0; b < bodies.size(); ++b)
			records[b].pv = pseudoV[b];
		restoreBodyIds();
		return stats;
	}

	// ------------------------------------------------------------------------- bodies in sweep order

	// A sweep reads and writes the two bodies of each contact in the schedule's order; stored by
	// id (creation order, unrelated to where grains lie in a pile) they are scattered over memory.
	// For a solve or a correction the bodies and their records are stored in the order in which
	// the sweep first meets them (bodies of no contact after), and the contacts' body ids point
	// there; restoreBodyIds puts everything back. The arithmetic is untouched: the same results,
	// bit for bit.
	void Solver::renumberBodies()
	{
		const int nb = int(bodies.size());
		slotOfBody.assign(nb, -1);
		bodyOfSlot.clear();
		bodyOfSlot.reserve(nb);
		const auto place = [&](int id) {
			if (slotOfBody[id] < 0) slotOfBody[id] = int(bodyOfSlot.size()), bodyOfSlot.push_back(id);
		};
		for (size_t k = 0; k < contacts.size(); ++k)
			place(contacts.info[k].b1), place(contacts.info[k].b2);
		for (int id = 0; id < nb; ++id)
			place(id);
		permuteBodies(bodyOfSlot, slotOfBody);
		renumbered = true;
	}

	void Solver::restoreBodyIds()
	{
		if (!renumbered) return;
		permuteBodies(slotOfBody, bodyOfSlot);
		renumbered = false;
	}

	// bodies[i] ← bodies[from[i]], the same for records; every contact's body b becomes to[b].
	void Solver::permuteBodies(const std::vector<int>& from, const std::vector<int>& to)
	{
		std::vector<Body>       b(bodies.size());
		std::vector<BodyRecord> r(records.size());
		for (size_t i = 0; i < from.size(); ++i)
			b[i] = bodies[from[i]], r[i] = records[from[i]];
		bodies.swap(b);
		records.swap(r);
		for (size_t k = 0; k < contacts.size(); ++k) {
			ContactInfo& c = contacts.info[k];
			c.b1 = to[c.b1], c.b2 = to[c.b2];
			if (contacts.state[k].kernel < 0) contacts.sphere[k].b1 = c.b1, contacts.sphere[k].b2 = c.b2;
		}
	}

	// ------------------------------------------------------------------------- export

	// The law's Delassus matrix W as COO triplets, blocks A_a F_a K_ab F_bᵀ with
	// K_ab = s_a s_b (diag(1/m) − [c_a]x I⁻¹ [c_b]x) summed over the bodies contacts a and b share
	// (s = +1 on body 2, −1 on body 1).
	void Solver::delassusTriplets(std::vector<long>& rows, std::vector<long>& cols, std::vector<double>& vals) const
	{
		std::vector<std::vector<std::pair<int, int>>> incident(bodies.size()); // (contact, side)
		for (size_t a = 0; a < contacts.size(); ++a) {
			const ContactInfo& c = contacts.info[a];
			if (records[c.b1].dynamic) incident[c.b1].push_back({ int(a), 0 });
			if (records[c.b2].dynamic) incident[c.b2].push_back({ int(a), 1 });
		}
		for (size_t id = 0; id < bodies.size(); ++id) {
			const Body& body = bodies[id];
			for (const auto& [a, sa] : incident[id])
				for (const auto& [b, sb] : incident[id]) {
					const ContactInfo &ca = contacts.info[a], &cb = contacts.info[b];
					const Real         sign = (sa ? 1 : -1) * (sb ? 1 : -1);
					const Matrix3r     K    = sign * (Matrix3r(body.invM.asDiagonal()) - skew(sa ? ca.c2 : ca.c1) * body.invI * skew(sb ? cb.c2 : cb.c1));
					const Matrix3r     Wab  = ca.A.asDiagonal() * (ca.frame * K * cb.frame.transpose());
					for (int i = 0; i < 3; ++i)
						for (int j = 0; j < 3; ++j) {
							rows.push_back(3 * a + i);
							cols.push_back(3 * b + j);
							vals.push_back(double(Wab(i, j)));
						}
				}
		}
	}

} // namespace cd
} // namespace yade
