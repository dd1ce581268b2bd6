// Contact Dynamics solver core: the data of one time step's problem.
//
// Everything here is plain data in flat arrays, filled by a host (the YADE adapter,
// ContactDynamicsIntegrator, or a test) and read by the solver (Solver.hpp). Nothing refers to a
// YADE object; bodies are indexed by their id, contacts by their place in the ContactSet, which
// the schedules may permute (ContactInfo::origin keeps the host's own index).
//
// Notation (docs/method.md has the full table): per contact, the local frame F (rows n, t1, t2),
// lever arms c1, c2 (contact point minus the body centres), the Delassus block W = F K Fᵀ, the
// law's scaling A = diag(1/(1+en), 1/(1+et), 1/(1+et)) and offset s, the impulse r (on body 2,
// local frame) and the local velocity U (body 2 relative to body 1). The law asks
// Ũ = A(U + s) and r to obey Signorini–Coulomb.
#pragma once

#include <lib/base/Math.hpp>

#include <vector>

namespace yade {
namespace cd {

	/*! One body's unknowns: what a sweep reads and writes (indexed by body id). */
	struct Body {
		Vector3r v    = Vector3r::Zero(); // velocity and angular velocity (u_free, then u_f)
		Vector3r w    = Vector3r::Zero();
		Vector3r invM = Vector3r::Zero(); // inverse mass per global axis; 0 on blocked or kinematic axes
		Matrix3r invI = Matrix3r::Zero(); // inverse inertia (global frame); blocked rows/columns zero
	};

	/*! The rest of a body's step data (indexed by body id). */
	struct BodyRecord {
		Vector3r vi = Vector3r::Zero(), wi = Vector3r::Zero(); // velocities at the start of the step (u_i)
		Vector3r pv = Vector3r::Zero(), pw = Vector3r::Zero(); // pseudo-velocities of the position correction (ũ)
		bool     dynamic = false;        // moved by the solve (obstacles are never written)
		Real     isoInvM = -1, isoInvI = -1; // scalar 1/m and 1/I when isotropic and unblocked, else −1
	};

	/*! What the host knows of a contact and the solver's per-contact results that the sweeps do
	 *  not read (the cold part of the contact set). */
	struct ContactInfo {
		// from the host (gather and contact frames)
		int      b1 = -1, b2 = -1;  // body ids
		long     origin = -1;       // the host's index of the contact
		Matrix3r frame;             // rows n, t1, t2, at q_m
		Vector3r c1, c2;            // contact point minus body centres, at q_m
		Vector3r point;             // contact point at q_m (slab schedule)
		Real     height = 0;        // contact point along −gravity at q_i (sweep order)
		Real     gapI = 0;          // gap at q_i (< 0: overlap)
		Real     gapM = 0;          // gap at q_m
		Real     refR = 1;          // reference radius (smaller of the two)
		Real     allowance = 0;     // overlap the contact may keep (CDPhys.overlapAllowance)
		Real     en = 0, et = 0;    // restitution coefficients
		Vector3r approach;          // landing velocity of the previous step (global frame; 0: none)
		Vector3r warmStart;         // impulse of the previous step (global frame)
		bool     shifted = false;   // body 2 is a periodic image: its velocity there is v2 + shift
		Vector3r shift = Vector3r::Zero(); // velocity of body 2's image relative to body 2 (global; YADE's Cell::intrShiftVel)
		// from the assembly (stage 5)
		Matrix3r W;                 // Delassus block
		Vector3r A;                 // law scaling
		Vector3r s;                 // law offset: e∘U_i (closed) or (2 g_m/h, 0, 0) (open)
		Vector3r Ui;                // U_i, local frame
		Vector3r Us = Vector3r::Zero(); // the image's shift velocity, local frame (part of every U of a shifted contact)
	};

	/*! What every pass over the contacts reads and writes (the sweep, the momentum pass, the
	 *  residual): 40 bytes, so that such a pass streams a small array besides the kernel's rows. */
	struct ContactState {
		Vector3r r;          // impulse, local frame [N·s]
		Real     mu;         // friction coefficient
		int      status;     // ContactStatus after the last update
		int      kernel;     // −1: sphere kernel; else the row in ContactSet::general
	};

	/*! The sphere kernel's constants of a contact whose lever arms lie along the normal (c_b = l_b n,
	 *  as for every sphere) between bodies that are isotropic (scalar 1/m, 1/I, nothing blocked)
	 *  or obstacles that do not rotate. Its Delassus block is diagonal,
	 *  diag(m1+m2, m1+m2+l1k1+l2k2, same), and an update reads only these numbers, the impulse and
	 *  the two bodies' velocities. The body ids come first: the update's first loads depend on them. */
	struct SphereRow {
		int      b1, b2;    // body ids
		Vector3r n, t1, t2; // local frame
		Vector3r Wd;        // diagonal of the law's block A·W
		Vector3r A;         // law scaling
		Vector3r bias;      // A∘s
		Real     l1, l2;    // lever arms along n
		Real     m1, m2;    // inverse masses (0: obstacle)
		Real     k1, k2;    // inverse inertias times lever arms
		Real     wnn;       // W_NN
	};

	/*! What the general kernel (any lever arms, anisotropic or blocked bodies, rotating obstacles)
	 *  needs beyond ContactInfo: the law's block and its inverse (the sticking branch). */
	struct GeneralRow {
		Matrix3r Wlaw;    // A·W
		Matrix3r WlawInv; // its inverse
	};

	/*! The contacts of a step, one set in arrays of records: the arrays a sweep reads
	 *  (the state: impulse, friction, status, kernel; the sphere kernel's rows) apart from the cold
	 *  ContactInfo. A contact takes the sphere kernel (kernel < 0: its SphereRow) or the general
	 *  one (kernel ≥ 0: its row in the side table `general`). There is one copy of every impulse
	 *  and status. */
	struct ContactSet {
		std::vector<ContactInfo>  info;   // cold: host inputs, W, A, s, U_i
		std::vector<ContactState> state;  // hot: impulse, friction, status, kernel
		std::vector<SphereRow>    sphere; // sphere kernel constants (valid where kernel < 0)
		std::vector<GeneralRow>  general; // side table (not permuted: kernel[] points into it)

		size_t size() const { return info.size(); }
		void   clear();
		/*! Append a contact given by the host; impulse and status are its warm start. */
		void add(const ContactInfo& c, Real mu, int status);
		/*! n more contacts with default records, which the host then fills in place (its
		 *  parallel gather: info and state as add() would give them). */
		void resize(size_t n);
		/*! Store the contacts in the given order: contact j ← contact order[j]. */
		void permute(const std::vector<long>& order);
	};

	/*! The solver's options (ContactDynamicsIntegrator's attributes of the same names). */
	struct Params {
		Real     h = 0;                // time step [s]
		Vector3r up = Vector3r::UnitZ(); // −gravity direction (slab cuts are horizontal)
		Real     tolerance = 1e-6;
		int      maxIter = 1000;
		int      checkEvery = 1;
		Real     relaxation = 1;       // over-relaxation ω (1: none; a separate kernel instance)
		int      schedule = 1;         // Schedule::Kind
		int      slabs = 2;
		int      slabsAcross = 1;      // columns per slab (Schedule::Slabs; 1: slabs only)
		bool     slabsOwnBodies = false; // Schedule::Slabs: every body owned by one part (the interface: contacts between two owners)
		bool     momentum = true;
		bool     sphereFastPath = true;
		bool     recordResidual = false;
		Real     positionTolerance = 1e-6;
		int      maxProjectionIter = 200;
		bool     correctionMomentum = false; // Nesterov's momentum in the position correction too (opt-in: see the integrator's attribute)
		long     parallelMinContacts = 2000;  // fewer contacts: the per-sweep stages run on the calling thread (same results; not a problem option, not in problem files)
		// Sweeps that follow the work (Solver.cpp, "worklist"): after worklistFullSweeps full
		// sweeps, a sweep visits only the contacts one of whose bodies an update changed
		// significantly in the sweep before or earlier in this one; a quiet partial sweep is
		// followed by a full one, and only a full sweep is followed by the exact residual test.
		// Significant: W_NN|Δr| > worklistThreshold · tolerance · ‖q‖ / √(contacts).
		bool     worklist = false;
		Real     worklistThreshold = 1;
		int      worklistFullSweeps = 1;
		bool     bodiesInSweepOrder = true; // the solve and the correction store the bodies in the order the sweep first meets them (the same results, bit for bit; false: by id, for benchmarks)
		int      stallWindow = 50; // momentum's stall guard: sweeps without a 1 % smaller change before the strict restart (benchmarks; not saved in problem files)
		bool     traceContacts = false; // diagnostics: SolveStats::traceChange/traceResidual (a residual pass per sweep; the solve itself is unchanged, bit for bit)
	};

	/*! What a solve reports (copied to the integrator's read-only attributes by the host). */
	struct SolveStats {
		int               iterations = 0;
		Real              residual = 0;
		bool              converged = true;
		int               nSticking = 0, nSliding = 0, nStatusChanges = 0;
		int               nInterface = 0, nColours = 0, nWide = 0;
		long              contactUpdates = 0;  // local updates made (sweeps × contacts without the worklist)
		int               fullSweeps = 0;      // sweeps over every contact (all of them without the worklist)
		int               residualChecks = 0;  // evaluations of the exact residual (each costs about a sweep)
		std::vector<Real> residualHistory;
		// Params::traceContacts: per sweep s and contact k (the schedule's order, ContactSet after
		// the solve), at index s·contacts + k: W_NN|Δr| of the sweep's update (0: not visited) and
		// the contact's natural-map residual after the sweep, both in velocity units [m/s]
		std::vector<float> traceChange, traceResidual;
	};

	/*! What the position correction reports. */
	struct CorrectionStats {
		int  iterations = 0;    // correction sweeps (0: nothing to correct)
		Real maxOverlap = 0;    // largest overlap beyond the allowance before correction, relative [-]
	};

} // namespace cd
} // namespace yade
