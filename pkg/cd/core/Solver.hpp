// Contact Dynamics solver core: stages 5–7 of Moreau's step on the flat problem of Problem.hpp.
//
//   5 assemble   per contact the Delassus block W, U_i, the law's A and s, the warm start in
//                the new frame, the kernel (sphere row or general side-table row), ‖q‖
//   6 solve      nonlinear Gauss–Seidel over the contacts in the schedule's order, each update
//                an exact local Signorini–Coulomb solve (LocalSolver.hpp), with Nesterov's
//                momentum and adaptive restart; the natural-map residual as stopping test
//   7 correct    the split position correction: normal pseudo-impulses P ≥ 0 that remove the
//                overlap the step created, by a projected Gauss–Seidel in the same schedule
//
// The host fills `bodies`, `records` and `contacts` (stages 1–4), calls the three stages in
// turn, and reads the velocities, pseudo-velocities, impulses and statistics back (stages 8–9).
// The solver never touches a host object; errors are std::invalid_argument naming the contact.
#pragma once

#include "Problem.hpp"
#include "Schedule.hpp"

namespace yade {
namespace cd {

	class Solver {
	public:
		std::vector<Body>       bodies;   // indexed by body id
		std::vector<BodyRecord> records;  // indexed by body id
		ContactSet              contacts;
		Real                    qNorm = 0; // ‖q‖: norm of the free local velocities of closing contacts (residual scale)

		/*! Stage 5. Throws if a contact joins two bodies that cannot move. */
		void assemble(const Params& p);
		/*! Stage 6: the impulses; bodies' velocities become u_f. */
		SolveStats solve(const Params& p);
		/*! Stage 7: pseudo-velocities records[b].pv, .pw. */
		CorrectionStats correct(const Params& p);

		/*! Local velocity U of contact k from the bodies' current velocities. */
		Vector3r localVelocity(long k) const;
		/*! The law's Delassus matrix (Ũ = W r + q over all contacts) as COO triplets; entries of
		 *  one position may repeat and are to be summed. */
		void delassusTriplets(std::vector<long>& rows, std::vector<long>& cols, std::vector<double>& vals) const;
		/*! The schedule of the last solve (empty before the first). */
		const Schedule& schedule() const { return order; }

	private:
		Schedule              order;
		bool                  sweepThreads = true; // the last solve's per-sweep stages may use threads (Params::parallelMinContacts)
		std::vector<Real>     rangeChange;  // per range, the sweep's Σ(W_NN|Δr|)²
		std::vector<int>      rangeStatus;  // per range, status changes
		std::vector<Real>     contactChange; // per contact, the sweep's (W_NN|Δr|)² (schedules summing per contact)
		std::vector<long>     rangeUpdates; // per range, the sweep's local updates
		std::vector<Real>     qShare;       // per contact, its share of ‖q‖²
		// the worklist (Params::worklist): per contact its two bodies' stamp slots (the body id, or
		// the never-written slot bodies.size() for an obstacle); per slot the last sweep in which an
		// update changed that body significantly, (W_NN|Δr|)² > workThreshold2
		std::vector<int>      stampSlot;
		std::vector<int>      stamp;
		Real                  workThreshold2 = 0;
		int                   sweepIndex     = 0;
		/*! How a sweep visits the contacts: all of them (Full), all of them stamping the bodies of
		 *  significant updates (Marking), or only those a stamp makes active (Partial). */
		enum SweepMode { Full = 0, Marking = 1, Partial = 2 };
		std::vector<Vector3r> rPrev;        // momentum: impulses after the previous sweep
		std::vector<Vector3r> vPrev, wPrev; // momentum: body velocities after the previous sweep

		/*! One contact's row of the position correction: all that a correction sweep reads. */
		struct CorrectionRow {
			Vector3r n;       // normal (sphere-kernel rows)
			Real     m1, m2;  // inverse masses (sphere-kernel rows; 0: obstacle)
			Real     overlap; // (−a − g_f)/refR without pseudo-velocities: overlap beyond the allowance [-]
			Real     lag;     // h/(2 refR): normal pseudo-velocity → relative overlap
			Real     gain;    // (2/h) refR / W_NN: relative overlap → pseudo-impulse
			Real     P;       // normal pseudo-impulse
			int      b1, b2;
			bool     sphere;  // false: through ContactInfo (general rows)
		};
		std::vector<CorrectionRow> corrections;
		std::vector<Vector3r>      pseudoV; // translational pseudo-velocities during the correction
		std::vector<Real>          pPrev;   // correction momentum: pseudo-impulses after the previous sweep
		std::vector<Vector3r>      pvPrev, pwPrev; // correction momentum: pseudo-velocities after the previous sweep

		void     buildSphereRow(long k, bool allowed);
		Vector3r sphereVelocity(const SphereRow& c) const;
		void     applySphereImpulse(const SphereRow& c, const Vector3r& dr);
		void     applyImpulse(const ContactInfo& c, const Vector3r& dr);
		template <bool Relaxed> Real updateContact(long k, Real omega, bool& changed);
		template <bool Relaxed> Real updateGeneral(long k, Real omega, bool& changed);
		template <bool Relaxed, int Mode, bool PerContact> Real sweepRange(long begin, long end, Real omega, int& nChanged, long& updates);
		template <bool Relaxed, int Mode, bool PerContact> Real sweepAll(Real omega, int& nChanged, long& updates);
		template <bool Relaxed> Real sweep(Real omega, int mode, bool perContact, int& nChanged, long& updates);
		void     startWorklist(const Params& p, Real scale);
		// Params::bodiesInSweepOrder: slot[id] is the body's place while a solve or a correction
		// runs (bodies, records and the contacts' body ids renumbered), ids[slot] its id
		std::vector<int> slotOfBody, bodyOfSlot;
		bool             renumbered = false;
		void             renumberBodies();
		void             restoreBodyIds();
		void             permuteBodies(const std::vector<int>& from, const std::vector<int>& to);
		void     recordTrace(SolveStats& stats) const;
		Real     contactResidual2(long k) const;
		void     startMomentum();
		void     extrapolate(Real beta);
		void     extrapolateRange(long begin, long end, Real beta);
		Real     residual(SolveStats& stats);
		std::vector<Real> residual2; // residual(): every contact's |e|², filled in parallel, summed in contact order
		Vector3r localPseudoVelocity(const ContactInfo& c) const;
		void     applyPseudoImpulse(const ContactInfo& c, Real dP);
		Real     correctionRange(long begin, long end, bool forward, bool complementarity);
		void     extrapolateCorrection(Real beta);
	};

} // namespace cd
} // namespace yade
