// Contact Dynamics plugin for YADE: Moreau's time-stepping integrator.
//
// Architecture
// ------------
// A CD scene is YADE's usual engine list with rigid-contact classes in place of the soft ones:
//
//   ForceResetter
//   InsertionSortCollider([Bo1_Sphere_CDAabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb()])
//   InteractionLoop([Ig2_Sphere_Sphere_CDScGeom(), Ig2_Wall_Sphere_CDScGeom(), Ig2_Facet_Sphere_CDScGeom()],
//                   [Ip2_FrictMat_FrictMat_CDPhys()], [Law2_ScGeom_CDPhys_Coulomb()])
//   ContactDynamicsIntegrator(gravity=...)
//
// The InteractionLoop, at the positions q_i of the step start, creates a contact for every pair
// closer than the alert distance and erases the far ones. This engine then runs Moreau's
// midpoint step (paper §II.3) in nine stages, numbered as in docs/method.md. The engine is a thin
// adapter around the solver core (pkg/cd/core: no YADE object is touched there): stages 1–4 and
// 8–9 move data between YADE and the core's flat arrays, stages 5–7 are the core's.
//
//   1 gatherContacts          every CDPhys contact into the core's contact set, sorted by height
//                             along −gravity (ties by ids), with its start-of-step gap and warm start
//   2 predictPositions        q_m = q_i + h/2 u_i
//   3 updateContactFrames     ScGeom recomputed at q_m by the contact's own Ig2 functor
//   4 computeFreeVelocities   u_free = u_i + h M⁻¹ (F_ext + m g)
//   5 assembleLocalProblems   (core) local frame, Delassus block W_αα, law offsets per contact
//   6 solveImpulses           (core) nonlinear Gauss–Seidel over contacts (Signorini–Coulomb, exact cone),
//                             in the order of a schedule (schedule: height, colours, slabs)
//   7 correctPositions        (core) split projection: removes only the overlap that the step created,
//                             through pseudo-velocities that are never stored
//   8 updatePositions         q_f = q_m + h/2 (u_f + ũ)
//   9 storeResults            impulses (warm start), forces, O.forces, energy, collider hint
//
// Conventions: the local frame of a contact is (n, t1, t2), n from body 1 to body 2 (ScGeom's);
// r is the impulse on body 2 [N·s], r_N ≥ 0 in compression; U is the velocity of body 2
// relative to body 1 at the contact point, U_N > 0 when the gap opens.
//
// Contact law per contact α, with gap g_m at q_m:
//   closed (g_m ≤ 0): Signorini–Coulomb on Ũ = (U_f + e U_i)/(1 + e) (Moreau's restitution mean,
//                     e = en on the normal, et on the tangent);
//   open   (g_m > 0): Signorini–Coulomb on Ũ = U_f + (2 g_m / h) e_N, i.e. the gap at the end of
//                     the step, g_m + h/2 U_f,N, must stay ≥ 0 (the contact "lands" exactly).
// A landed contact keeps a closing velocity; at the next step it is closed, its impulse stops
// it, and correctPositions removes the overlap the half-step predictor made. So an inelastic
// impact neither bounces back nor leaves a lasting overlap, wherever it falls in the step.
//
// ContactDynamicsIntegrator derives from NewtonIntegrator so that YADE's collider (stride /
// Verlet mode), utils.unbalancedForce (gravity) and other utilities recognise it.
#pragma once

#include <lib/base/Math.hpp>
#include <core/Interaction.hpp>
#include <pkg/dem/NewtonIntegrator.hpp>

#include "core/Solver.hpp"

namespace yade {

class Scene;

class ContactDynamicsIntegrator : public NewtonIntegrator {
public:
	void action() override;
	void postLoad(ContactDynamicsIntegrator&);
	//! The schedule's name for the solver core's code (Schedule::Kind), and back; "" / 0 when unknown.
	static std::string scheduleName(int code);
	static int         scheduleCode(const std::string& name);

	/*! Alert distance of a pair (see CDGeom.hpp); scene's CD engine supplies the parameters. */
	static Real alertDistance(const Scene* scene, Real rmin, Real speedSum);
	static const ContactDynamicsIntegrator* find(const Scene* scene);

private:
	// schedule and sweepOrder as postLoad last saw them: tells which of the two a user (or an
	// archive, which holds only sweepOrder) has just set
	std::string scheduleSeen = "height";
	int         sweepOrderSeen = 1;
	void        syncSchedule(); // keeps schedule and sweepOrder in step (postLoad)
	/*! What the adapter keeps of a body to restore a failed step (indexed by body id). */
	struct StartOfStep {
		Vector3r    pos;
		Quaternionr ori;
		bool        active = false; // body exists and is handled by this engine
	};
	cd::Solver                           core;  // bodies, contacts and the solver (pkg/cd/core)
	std::vector<StartOfStep>             start;
	std::vector<shared_ptr<Interaction>> links; // the interaction of each contact, by ContactInfo::origin
	// Clumps: the solver moves a clump as one rigid body; its members follow it (Clump::moveMembers).
	std::vector<int>                     mover;        // body id -> the id the solver moves: itself, or its clump
	std::vector<int>                     clumps;       // ids of the clump bodies
	std::vector<std::pair<Vector3r, Vector3r>> memberLever; // by ContactInfo::origin: contact point minus the touching bodies' own centres, at q_m
	// Periodic cells (YADE's conventions, as NewtonIntegrator): the collider hint of a changing
	// cell, and the velocities before this step's homogeneous-deformation jump (to restore them)
	Real                                       cellMaxVelocitySq = 0;
	int                                        cellHomoDeform    = 0;                  // Cell.homoDeform of this step
	Matrix3r                                   cellDVelGrad      = Matrix3r::Zero();   // velGrad − prevVelGrad
	Vector3r                                   cellDSpin         = Vector3r::Zero();   // its rotational part
	bool                                       cellFlipped       = false;              // the prologue flipped the cell this step
	Matrix3r                                   prevCellHSize     = Matrix3r::Identity(); // the cell at the end of the step before (adoptCellFlip)
	bool                                       hasPrevCellHSize  = false;
	std::vector<std::pair<Vector3r, Vector3r>> beforeJump;

	cd::Params params() const;
	void       checkScene();
	void       checkInheritedAttributes() const;
	void       gatherContacts();
	std::string interactionProblem(const Interaction& I) const;
	void       predictPositions();
	void       moveClumpMembers();
	void       startCellStep();
	void       endCellStep();
	Vector3r   imageShift(const Interaction& I, bool midStep) const;
	void       adoptCellFlip(Cell& cell);
	Vector3r   imageShiftVelocity(const Vector3i& cellDist) const;
	void       checkClumpMember(const Body& b, const string& who);
	void       updateContactFrames();
	void       computeFreeVelocities();
	void       writeProblemFile();
	void       assembleLocalProblems();
	void       solveImpulses();
	void       correctPositions();
	void       updatePositions();
	void       storeResults();
	void       trackEnergy();
	void       restoreStartOfStep();

public:
// Test only (tests/runs/test_runstate.py builds a second copy of the plugin with it): one more
// serialized attribute, so that a checkpoint written before a change of the class layout can be
// shown to resume after it. Never defined in a normal build.
#ifdef YADECD_THROWAWAY_ATTRIBUTE
#define YADECD_THROWAWAY_ATTR ((int, throwawayAttribute, 7, , "Test-only serialized attribute (YADECD_THROWAWAY_ATTRIBUTE builds)."))
#else
#define YADECD_THROWAWAY_ATTR
#endif
	// clang-format off
	YADE_CLASS_BASE_DOC_ATTRS_CTOR_PY(ContactDynamicsIntegrator, NewtonIntegrator,
		"Moreau's Contact Dynamics (non-smooth, rigid-contact) time integrator [Moreau1988]_, replacing :yref:`NewtonIntegrator` in a CD scene. Each step: q_m = q_i + h/2·u_i; contact frames at q_m; an implicit velocity step in which all contact impulses are solved together by nonlinear Gauss–Seidel with the exact Signorini–Coulomb law (unilateral contact, Coulomb cone, Moreau's restitution mean); q_f = q_m + h/2·u_f. Contacts come from :yref:`Law2_ScGeom_CDPhys_Coulomb` / :yref:`CDPhys`. Gravity comes from :yref:`gravity<NewtonIntegrator.gravity>`; other forces in ``O.forces`` (``addF``, ``setPermF``, :yref:`GravityEngine`) enter the free velocity too. Fixed bodies and :yref:`blockedDOFs<State.blockedDOFs>` keep their velocity (moving walls are time-dependent obstacles). Results: contact forces in :yref:`CDPhys`, per-body totals in ``O.forces`` (gravity excluded, as with NewtonIntegrator), energies with ``O.trackEnergy``. Clumps of spheres (:yref:`Clump`) are moved as rigid bodies: their members' contacts and forces act on the clump, with lever arms from its centre of mass, and the members follow it; pairs within a clump never meet (YADE's collider). Periodic cells (``O.periodic``) follow YADE's conventions: a contact across the boundary is with body 2's image at x₂ + H·cellDist moving at v₂ + :yref:`Cell.velGrad`·H_prev·cellDist, a velGrad set by the user takes effect at the next step with NewtonIntegrator's velocity jump (:yref:`Cell.homoDeform` > 0) and convective term (homoDeform > 1); walls, facets and boxes have no image there and are refused. :yref:`damping<NewtonIntegrator.damping>` must stay 0, and the other inherited attributes it does not honour (``mask``, ``callbacks`` in builds that have them, ``exactAsphericalRot``, ``rotAlgorithm``, ``normalizeEvery``, ``niterOmelyan1998``, ``kinSplit``, ``dampGravity``) are refused at the first step when not at NewtonIntegrator's defaults. See the plugin's ``docs/method.md``.",
		((Real, tolerance, 1e-6, Attr::triggerPostLoad, "Convergence threshold of the Gauss–Seidel solve on the relative natural-map residual :yref:`residual<ContactDynamicsIntegrator.residual>` [-], in (0, 1)."))
		((int, maxIter, 1000, Attr::triggerPostLoad, "Maximum number of Gauss–Seidel sweeps per step (≥ 1). A step that stops here unconverged warns and counts in :yref:`nUnconverged<ContactDynamicsIntegrator.nUnconverged>`."))
		((int, checkEvery, 1, Attr::triggerPostLoad, "Evaluate the exact residual (a pass that costs about one sweep) at most every this many sweeps (≥ 1), and only after a sweep whose own velocity changes sqrt(Σ(W_NN|Δr|)²) fell below tolerance·‖q‖ (or every checked sweep with recordResidual)."))
		((Real, relaxation, 1.0, Attr::triggerPostLoad, "Over-relaxation ω of each local update, r ← P_C(r + ω(r_local − r)) [-], in (0, 2); 1 (the default) is plain Gauss–Seidel, swept by a kernel that carries no trace of ω. Open contacts always take r_local = 0. Once a step's sweeps stop contracting (no 1% improvement of the sweep's velocity change in 50 sweeps) the step finishes with ω = 1, since over-relaxation is not safe with friction. With ω ≠ 1 even a single contact is solved only to the tolerance, not exactly in one sweep. Where it helps (columns) and where it does not (piles, against momentum): docs/results.md."))
		((int, sweepOrder, 1, Attr::triggerPostLoad, "Deprecated integer code of :yref:`schedule<ContactDynamicsIntegrator.schedule>`, kept so that scripts and saved scenes of earlier releases still work: 1 'height', 4 'colours', 5 'slabs' (0, 2 and 3 are retired orders and an error). Setting it sets the schedule; it is saved with the scene in the schedule's stead."))
		((string, schedule, "height", (Attr::noSave | Attr::triggerPostLoad), "Order of the Gauss–Seidel sweeps (every one deterministic; momentum and the position correction follow the same order). ``'height'``: contacts by height along −gravity, upwards (a load change at the floor travels up the whole stack in one sweep). ``'colours'``: contacts grouped into colours that share no dynamic body (greedy, in height order), swept colour by colour, the contacts of a colour in parallel on O.numThreads threads (yade -j N). ``'slabs'``: the scene cut into :yref:`slabs<ContactDynamicsIntegrator.slabs>` vertical slabs of equal contact counts across its wider horizontal extent, each slab's inner contacts upwards by height, the slabs in parallel (O.numThreads threads), then the contacts of the bodies that touch two slabs, upwards, cut by cut (the even cuts in parallel, then the odd ones; what spans more than two slabs in colours of its own); with :yref:`slabsAcross<ContactDynamicsIntegrator.slabsAcross>` > 1 the slabs are cut into columns, a two-dimensional decomposition for more threads. Keeps the upward order that piles need. Results are bit-identical for any thread count with every schedule. Saved with the scene through its integer code :yref:`sweepOrder<ContactDynamicsIntegrator.sweepOrder>`. Which is fastest where: docs/performance.md."))
		((int, slabs, 2, Attr::triggerPostLoad, "Number of slabs of the 'slabs' :yref:`schedule<ContactDynamicsIntegrator.schedule>` (1–64, and slabs × :yref:`slabsAcross<ContactDynamicsIntegrator.slabsAcross>` at most 64): the most threads that schedule can use. Fixed by the user, not by the thread count, so that results do not depend on the threads. More slabs make the interface larger (the contacts of the bodies that straddle a cut, swept after the slabs, each cut by one thread); past about 8 slabs on a pile the slabs get thinner than a grain's neighbourhood and they stop scaling: cut them into columns instead (:yref:`slabsAcross<ContactDynamicsIntegrator.slabsAcross>`). How far each scales: docs/scale-out.md."))
		((int, slabsAcross, 1, (Attr::noSave | Attr::triggerPostLoad), "Columns per slab of the 'slabs' :yref:`schedule<ContactDynamicsIntegrator.schedule>` (1–64; :yref:`slabs<ContactDynamicsIntegrator.slabs>` × slabsAcross at most 64): with more than 1, every slab is cut along the other horizontal axis into this many columns of equal contact counts, and the schedule sweeps the columns' inner contacts in parallel, then the contacts of the bodies that touch two columns, in colours of groups that share no column (in parallel), then those touching three columns or more (one thread). A two-dimensional decomposition for more than about 8 threads, where slabs alone stop scaling (docs/scale-out.md). 1: slabs only, the order of earlier releases. Not saved with the scene (set it again after O.load; the pile scripts keep it in run.json)."))
		((bool, slabsOwnBodies, false, (Attr::noSave | Attr::triggerPostLoad), "How the 'slabs' :yref:`schedule<ContactDynamicsIntegrator.schedule>` divides the bodies among its parts (slabs, or columns with :yref:`slabsAcross<ContactDynamicsIntegrator.slabsAcross>` > 1). False (the default, the order of earlier releases): a contact is swept inside its part when every part its bodies touch is that one; the contacts of bodies that straddle a cut form the interface. True: every dynamic body is owned by the part that holds most of its contacts (the lowest on a tie), a part sweeps the contacts between its own bodies (and with obstacles), and the interface is only the contacts between bodies of two parts, grouped by that pair: on the full pile's fed step 1.8 % of the contacts instead of 5.0 % with two slabs, and a one-sweep speed-up modelled at 6.7× instead of 5.8× on 8 cores, 10.5× instead of 8.0× on 16 (docs/scale-out.md). Bit-identical for any thread count either way; the two give different (equally converged) solutions. Not saved with the scene (set it again after O.load; the pile scripts keep it in run.json)."))
		((Real, alertRatio, 0.05, Attr::triggerPostLoad, "Alert distance, static part, relative to the smaller radius of a pair [-], ≥ 0. A pair becomes a contact when its gap is below alertRatio·min(r1,r2) + alertSpeedFactor·dt·(|v1|+|v2|)."))
		((Real, alertSpeedFactor, 2.0, Attr::triggerPostLoad, "Alert distance, speed part: how many steps' worth of travel at the current speed a pair is watched ahead [-]. Must be ≥ 1 so that no contact closing within a step is missed (no tunnelling)."))
		((Real, positionTolerance, 1e-6, Attr::triggerPostLoad, "Position correction: largest overlap beyond a contact's allowance left at the end of a step, relative to the contact's reference radius [-], > 0. Smaller values cost more correction sweeps in dense packings (the correction is a Gauss–Seidel too)."))
		((int, maxProjectionIter, 200, Attr::triggerPostLoad, "Maximum sweeps of the position correction (≥ 1)."))
		((long, parallelMinContacts, 2000, (Attr::noSave | Attr::triggerPostLoad), "Fewest contacts at which the sweeps use several threads (the parallel stages of the 'colours' and 'slabs' :yref:`schedules<ContactDynamicsIntegrator.schedule>`, and the momentum's passes over bodies); with fewer, they run on the calling thread; 0 always uses the threads (≥ 0). Results are the same either way (bit for bit). Where threads pay on two cores, and why they must not share a core with another busy process: docs/performance.md. Not saved with the scene."))
		((bool, correctionMomentum, false, Attr::noSave, "Accelerate the position correction's Gauss–Seidel with Nesterov's momentum and adaptive restart, as the solve (:yref:`momentum<ContactDynamicsIntegrator.momentum>`): P_y = max(0, P + β(P − P_prev)), sweeps always upwards, restart when a sweep ends with a largest overlap 1.2× the previous one's; its stopping test also bounds the separation of rows that still push (complementarity), which an extrapolated start can create. False (the default, for continuity with the reference pile ensembles): plain projected Gauss–Seidel in alternating directions. Its measured gains and checks on piles: docs/performance.md. Not saved with the scene, so that scenes and checkpoints of earlier builds still load: set it again after O.load."))
		((bool, momentum, true, , "Accelerate the Gauss–Seidel sweeps with Nesterov's momentum and adaptive restart (accelerated projected Gauss–Seidel): after a sweep gives the impulses x_k, the next sweep starts from y_k = P_C(x_k + β_k (x_k − x_{k−1})), β_k = (t_k − 1)/t_{k+1}, t_{k+1} = (1 + √(1 + 4t_k²))/2, t_1 = 1; t restarts at 1 (β = 0) when a sweep changes the velocities clearly more than the sweep before (adaptive restart, O'Donoghue & Candès 2015): more than 1.2× the previous one, or, once the sweeps stall (no 1% progress in 50 sweeps), more than the previous one. The first sweep is plain Gauss–Seidel, so a single contact is still solved exactly in one sweep. The extrapolation costs a pass over bodies and contacts. Its measured gains: docs/performance.md."))
		((bool, sphereFastPath, true, , "Sweep contacts whose lever arms lie along the normal, between isotropic bodies (every sphere–sphere and sphere–static-obstacle contact without blocked DOFs), through a compact copy with a diagonal Delassus block: the same updates to rounding, faster (docs/performance.md). False: every contact takes the general 3×3 path."))
		((bool, warnUnconverged, true, , "Log a warning for every step whose solve did not converge."))
		((bool, recordResidual, false, , "Record the residual after each checked sweep in :yref:`residualHistory<ContactDynamicsIntegrator.residualHistory>` (last step only)."))
		((int, iterations, 0, Attr::readonly, "Gauss–Seidel sweeps done in the last step. |yupdate|"))
		((Real, residual, 0, Attr::readonly, "Relative residual reached in the last step [-]: sqrt(Σ_α |e_α|²)/‖q‖ with e_α the natural-map residual of contact α in velocity units (ρ_α = 1/W_NN,α) and ‖q‖ the norm of the free local velocities q_α = A(U_free + s) (law offsets included) of the contacts that would close without impulses (q_N < 0). 0 without contacts. |yupdate|"))
		((bool, converged, true, Attr::readonly, "Whether the last step's solve met :yref:`tolerance<ContactDynamicsIntegrator.tolerance>`. |yupdate|"))
		((long, nUnconverged, 0, , "Number of steps whose solve did not converge (cumulative; may be reset). |yupdate|"))
		((int, nContacts, 0, Attr::readonly, "Contacts (real CD interactions, gaps within the alert distance included) in the last step. |yupdate|"))
		((int, nSticking, 0, Attr::readonly, "Contacts sticking after the last solve. |yupdate|"))
		((int, nSliding, 0, Attr::readonly, "Contacts sliding after the last solve. |yupdate|"))
		((int, nStatusChanges, 0, Attr::readonly, "Contacts whose status changed during the last sweep of the last step. |yupdate|"))
		((int, projectionIterations, 0, Attr::readonly, "Sweeps of the position correction in the last step (0: nothing to correct). |yupdate|"))
		((Real, maxCorrectedOverlap, 0, Attr::readonly, "Largest overlap the last step created before correction, relative to the reference radius [-]. |yupdate|"))
		((int, nInterface, 0, (Attr::readonly | Attr::noSave), "Contacts of the last step's 'slabs' sweep swept after the parts (slabs, or columns with :yref:`slabsAcross<ContactDynamicsIntegrator.slabsAcross>` > 1): by default the contacts of bodies that touch more than one part, grouped by the parts their bodies touch; with :yref:`slabsOwnBodies<ContactDynamicsIntegrator.slabsOwnBodies>` the contacts between bodies owned by two parts, grouped by that pair. The groups are swept in colours that share no part (with slabs only: the even cuts at once, then the odd ones; with two slabs: one cut, swept by one thread). Not saved: 0 after O.load until the next step. |yupdate|"))
		((int, nColours, 0, (Attr::readonly | Attr::noSave), "Colours of the last step's 'colours' sweep (65 means some contacts fell in the sequential overflow group). Not saved: 0 after O.load until the next step. |yupdate|"))
		((vector<Real>, residualHistory, , Attr::readonly, "Residual after each checked sweep of the last step, if :yref:`recordResidual<ContactDynamicsIntegrator.recordResidual>`. |yupdate|"))
		((string, problemFile, "", Attr::noSave, "Write the next step's problem (the solver core's input at stage 5: bodies with their free velocities, contacts with frames, gaps and warm starts, and the options) to this file, then clear the attribute. The core tests and ``cd_core_bench`` solve such files without YADE (format: pkg/cd/core/ProblemFile.hpp). Not saved with the scene."))
		YADECD_THROWAWAY_ATTR
		((int, contactDissipIx, -1, (Attr::hidden | Attr::noSave), "Energy index: contact dissipation."))
		((int, extWorkIx, -1, (Attr::hidden | Attr::noSave), "Energy index: work of O.forces."))
		((int, kinematicWorkIx, -1, (Attr::hidden | Attr::noSave), "Energy index: work on kinematic bodies."))
		((int, posCorrIx, -1, (Attr::hidden | Attr::noSave), "Energy index: position correction."))
		,
		/* ctor */ damping = 0;
		,
		/* py */
		.def("solveLocal", &ContactDynamicsIntegrator::pySolveLocal, (boost::python::arg("W"), boost::python::arg("b"), boost::python::arg("mu")), "Solve one local Signorini–Coulomb problem U = W r + b exactly; return (r, status) with status 0 open, 1 sticking, 2 sliding. W must be symmetric positive definite and mu a finite number ≥ 0 (ValueError otherwise). Exposed for tests and cross-checks.").staticmethod("solveLocal")
		.def("problem", &ContactDynamicsIntegrator::pyProblem, "The frictional contact problem of the last step, Ũ = W·r + q with (r, Ũ) obeying the Signorini–Coulomb law per contact (local frames, normal first), as a dict of numpy arrays: ``rows``, ``cols``, ``vals`` (the sparse 3n×3n Delassus matrix W of the law in COO triplets; repeated positions are to be summed), ``q`` (3n), ``mu`` (n), ``r`` (3n impulses found [N·s]), ``ids`` (n×2 body ids). With restitution 0 this is Siconos' FrictionContactProblem(3, n, W, q, mu); ``yadecd.export.fclib`` turns it into scipy matrices and FCLIB HDF5 files. Empty arrays before the first step, and after O.load until the next step.")
		.def("naturalMapResidual", &ContactDynamicsIntegrator::pyResidual, (boost::python::arg("r"), boost::python::arg("U"), boost::python::arg("mu"), boost::python::arg("rho") = 1.0), "Natural-map residual vector of one contact, (r − P_C(r − ρ Û))/ρ with Û = U + μ|U_T| e_N; rho > 0 and mu ≥ 0, finite (ValueError otherwise).").staticmethod("naturalMapResidual")
	);
	// clang-format on
	boost::python::dict         pyProblem() const;
	static boost::python::tuple pySolveLocal(const Matrix3r& W, const Vector3r& b, Real mu);
	static Vector3r             pyResidual(const Vector3r& r, const Vector3r& U, Real mu, Real rho);
	DECLARE_LOGGER;
};
REGISTER_SERIALIZABLE(ContactDynamicsIntegrator);

} // namespace yade
