// Contact Dynamics plugin for YADE: Moreau's time-stepping integrator (see the header for the
// architecture, the contact law and the sign conventions).
#include "ContactDynamicsIntegrator.hpp"
#include "core/LocalSolver.hpp"
#include "core/ProblemFile.hpp"
#include "core/Schedule.hpp"
#include "CDPhys.hpp"
#include <core/Cell.hpp>
#include <core/Clump.hpp>
#include <core/Scene.hpp>
#include <pkg/dem/ScGeom.hpp>

#ifdef YADE_OPENMP
#include <omp.h>
#endif
#include <algorithm>
#include <numeric>
#include <fstream>
#include <sstream>

namespace yade {

YADE_PLUGIN((ContactDynamicsIntegrator));
CREATE_LOGGER(ContactDynamicsIntegrator);

namespace {
	// Default alert parameters, for functors used in a scene without the CD engine.
	constexpr Real defaultAlertRatio = 0.05, defaultAlertSpeedFactor = 2.0;

	std::string pairName(int id1, int id2) { return "(#" + std::to_string(id1) + ", #" + std::to_string(id2) + ")"; }

	// Any unit vector orthogonal to n, chosen deterministically from n alone.
	Vector3r orthogonalUnit(const Vector3r& n)
	{
		const Vector3r a = (math::abs(n[0]) < 0.57) ? Vector3r::UnitX() : Vector3r::UnitY();
		return n.cross(a).normalized();
	}
	bool finite(const Vector3r& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }
	// Rotate an orientation by the rotation vector w·dt (exact for constant w).
	void rotate(Quaternionr& ori, const Vector3r& w, Real dt)
	{
		const Real angle = w.norm() * dt;
		if (angle == 0) return;
		ori = Quaternionr(AngleAxisr(angle, w.normalized())) * ori;
		ori.normalize();
	}
}

// ----------------------------------------------------------------------------- set-up helpers

std::string ContactDynamicsIntegrator::scheduleName(int code)
{
	switch (code) {
		case cd::Schedule::Height: return "height";
		case cd::Schedule::Colours: return "colours";
		case cd::Schedule::Slabs: return "slabs";
		default: return "";
	}
}

int ContactDynamicsIntegrator::scheduleCode(const std::string& name)
{
	for (int code : { int(cd::Schedule::Height), int(cd::Schedule::Colours), int(cd::Schedule::Slabs) })
		if (scheduleName(code) == name) return code;
	return 0;
}

void ContactDynamicsIntegrator::postLoad(ContactDynamicsIntegrator&)
{
	auto bad = [](const std::string& what) { throw std::invalid_argument("ContactDynamicsIntegrator." + what); };
	if (!(tolerance > 0 && tolerance < 1)) bad("tolerance=" + std::to_string(tolerance) + ": must lie in (0, 1) (a relative residual).");
	if (maxIter < 1) bad("maxIter=" + std::to_string(maxIter) + ": must be at least 1.");
	if (checkEvery < 1) bad("checkEvery=" + std::to_string(checkEvery) + ": must be at least 1.");
	if (!(alertRatio >= 0)) bad("alertRatio=" + std::to_string(alertRatio) + ": must be ≥ 0.");
	if (!(alertSpeedFactor >= 1)) bad("alertSpeedFactor=" + std::to_string(alertSpeedFactor) + ": must be ≥ 1, or contacts closing within a step are missed.");
	if (!(positionTolerance > 0)) bad("positionTolerance=" + std::to_string(positionTolerance) + ": must be a positive number.");
	if (!(relaxation > 0 && relaxation < 2)) bad("relaxation=" + std::to_string(relaxation) + ": must lie in (0, 2).");
	syncSchedule();
	if (slabs < 1 || slabs > 64) bad("slabs=" + std::to_string(slabs) + ": must lie in 1..64.");
	if (slabsAcross < 1 || slabsAcross > 64) bad("slabsAcross=" + std::to_string(slabsAcross) + ": must lie in 1..64.");
	if (slabs * slabsAcross > 64)
		bad("slabs=" + std::to_string(slabs) + " with slabsAcross=" + std::to_string(slabsAcross) + ": the parts (slabs × slabsAcross) must be at most 64.");
	if (parallelMinContacts < 0) bad("parallelMinContacts=" + std::to_string(parallelMinContacts) + ": must be 0 (always use the threads) or more.");
	if (maxProjectionIter < 1) bad("maxProjectionIter=" + std::to_string(maxProjectionIter) + ": must be at least 1.");
}

void ContactDynamicsIntegrator::syncSchedule()
{
	auto bad = [](const std::string& what) { throw std::invalid_argument("ContactDynamicsIntegrator." + what); };
	// The schedule has a name (schedule, not saved) and a code (sweepOrder, saved): whichever of
	// the two changed since the last call sets the other. An archive sets only the code.
	const bool nameSet = schedule != scheduleSeen, codeSet = sweepOrder != sweepOrderSeen;
	if (nameSet) {
		const int code = scheduleCode(schedule);
		if (!code) bad("schedule='" + schedule + "': must be 'height', 'colours' or 'slabs'.");
		if (codeSet && sweepOrder != code)
			bad("schedule='" + schedule + "' and sweepOrder=" + std::to_string(sweepOrder) + " disagree: set schedule only (sweepOrder is its deprecated code).");
		sweepOrder = code;
	} else if (codeSet) {
		if (sweepOrder == 0 || sweepOrder == 2 || sweepOrder == 3)
			bad("sweepOrder=" + std::to_string(sweepOrder) + ": a retired order; set schedule='height', 'colours' or 'slabs' (docs/results.md says why the others were retired).");
		if (scheduleName(sweepOrder).empty()) bad("sweepOrder=" + std::to_string(sweepOrder) + ": must be 1 (schedule 'height'), 4 ('colours') or 5 ('slabs').");
		schedule = scheduleName(sweepOrder);
	}
	scheduleSeen   = schedule;
	sweepOrderSeen = sweepOrder;
}

const ContactDynamicsIntegrator* ContactDynamicsIntegrator::find(const Scene* scene)
{
	for (const auto& e : scene->engines)
		if (auto* cd = dynamic_cast<const ContactDynamicsIntegrator*>(e.get())) return cd;
	return nullptr;
}

Real ContactDynamicsIntegrator::alertDistance(const Scene* scene, Real rmin, Real speedSum)
{
	const ContactDynamicsIntegrator* cd = find(scene);
	const Real                       ratio = cd ? cd->alertRatio : defaultAlertRatio, k = cd ? cd->alertSpeedFactor : defaultAlertSpeedFactor;
	return ratio * rmin + k * scene->dt * speedSum;
}

boost::python::tuple ContactDynamicsIntegrator::pySolveLocal(const Matrix3r& W, const Vector3r& b, Real mu)
{
	if (!(mu >= 0) || !std::isfinite(mu)) throw std::invalid_argument("solveLocal: mu must be a finite number ≥ 0.");
	const bool symmetric = W.allFinite() && (W - W.transpose()).norm() <= 1e-12 * W.norm();
	if (!symmetric || W.llt().info() != Eigen::Success) throw std::invalid_argument("solveLocal: W must be symmetric positive definite.");
	Vector3r r = Vector3r::Zero();
	const int status = int(cd::solveLocal(W, b, mu, r));
	return boost::python::make_tuple(r, status);
}

namespace {
	// A numpy array (a copy) of a flat vector, through numpy.frombuffer.
	template <typename T> boost::python::object toNumpy(const std::vector<T>& v, const char* dtype)
	{
		namespace py = boost::python;
		py::object bytes(py::handle<>(PyBytes_FromStringAndSize(reinterpret_cast<const char*>(v.data()), Py_ssize_t(v.size() * sizeof(T)))));
		return py::import("numpy").attr("frombuffer")(bytes, dtype).attr("copy")();
	}
}

boost::python::dict ContactDynamicsIntegrator::pyProblem() const
{
	std::vector<long>   rows, cols, pairs;
	std::vector<double> vals, q(3 * core.contacts.size()), mu, r;
	core.delassusTriplets(rows, cols, vals);
	for (size_t a = 0; a < core.contacts.size(); ++a) {
		const cd::ContactInfo& c    = core.contacts.info[a];
		const Vector3r         Ulaw = c.A.cwiseProduct(core.localVelocity(long(a)) + c.s); // the law's velocity at the solution
		for (int i = 0; i < 3; ++i) {
			q[3 * a + i] = double(Ulaw[i]);
			r.push_back(double(core.contacts.state[a].r[i]));
		}
		mu.push_back(double(core.contacts.state[a].mu));
		pairs.push_back(c.b1);
		pairs.push_back(c.b2);
	}
	for (size_t k = 0; k < vals.size(); ++k) // q = Ũ − W r
		q[rows[k]] -= vals[k] * r[cols[k]];
	boost::python::dict d;
	d["rows"] = toNumpy(rows, "int64");
	d["cols"] = toNumpy(cols, "int64");
	d["vals"] = toNumpy(vals, "float64");
	d["q"]    = toNumpy(q, "float64");
	d["mu"]   = toNumpy(mu, "float64");
	d["r"]    = toNumpy(r, "float64");
	d["ids"]  = toNumpy(pairs, "int64").attr("reshape")(-1, 2);
	return d;
}

Vector3r ContactDynamicsIntegrator::pyResidual(const Vector3r& r, const Vector3r& U, Real mu, Real rho)
{
	if (!(rho > 0) || !std::isfinite(rho)) throw std::invalid_argument("naturalMapResidual: rho must be a finite number > 0.");
	if (!(mu >= 0) || !std::isfinite(mu)) throw std::invalid_argument("naturalMapResidual: mu must be a finite number ≥ 0.");
	return cd::naturalMapResidual(r, U, mu, rho);
}

// ----------------------------------------------------------------------------- the step

void ContactDynamicsIntegrator::action()
{
	timingDeltas->start();
	checkScene();
	startCellStep();                  // periodic cells: velGrad changes, as NewtonIntegrator
	gatherContacts();                 // 1
	timingDeltas->checkpoint("gatherContacts");
	predictPositions();               // 2
	try {
		updateContactFrames();        // 3
		timingDeltas->checkpoint("updateContactFrames");
		computeFreeVelocities();      // 4
		if (!problemFile.empty()) writeProblemFile();
		assembleLocalProblems();      // 5
		timingDeltas->checkpoint("assembleLocalProblems");
		solveImpulses();              // 6
		timingDeltas->checkpoint("solveImpulses");
		correctPositions();           // 7
		timingDeltas->checkpoint("correctPositions");
		updatePositions();            // 8
	} catch (...) {
		restoreStartOfStep(); // a failed step leaves the scene as it found it
		throw;
	}
	storeResults();                   // 9
	endCellStep();
	timingDeltas->checkpoint("storeResults");
}

// The core's options, from this engine's attributes and the scene.
cd::Params ContactDynamicsIntegrator::params() const
{
	cd::Params p;
	p.h                 = scene->dt;
	p.up                = gravity.squaredNorm() > 0 ? Vector3r(-gravity.normalized()) : Vector3r::UnitZ();
	p.tolerance         = tolerance;
	p.maxIter           = maxIter;
	p.checkEvery        = checkEvery;
	p.relaxation        = relaxation;
	p.schedule          = sweepOrder;
	p.slabs             = slabs;
	p.slabsAcross       = slabsAcross;
	p.slabsOwnBodies    = slabsOwnBodies;
	p.momentum          = momentum;
	p.sphereFastPath      = sphereFastPath;
	p.recordResidual    = recordResidual;
	p.positionTolerance = positionTolerance;
	p.maxProjectionIter = maxProjectionIter;
	p.correctionMomentum = correctionMomentum;
	p.parallelMinContacts = parallelMinContacts;
	return p;
}

// Attributes inherited from NewtonIntegrator that Contact Dynamics does not honour: a non-default
// value would be ignored without a word, so it is refused by name (before anything moves).
void ContactDynamicsIntegrator::checkInheritedAttributes() const
{
	auto refuse = [](const string& what, const string& why) {
		throw std::invalid_argument("ContactDynamicsIntegrator." + what + ": " + why + " Leave it at NewtonIntegrator's default.");
	};
	const string rotation = "Contact Dynamics turns bodies by their rotation vector (q_m = q_i + h/2·w); the aspherical rotation options have no effect.";
	if (mask != -1) refuse("mask=" + std::to_string(mask), "body masks are not honoured: every dynamic body moves.");
#ifdef YADE_BODY_CALLBACK // only YADE builds with body callbacks have the attribute
	if (!callbacks.empty()) refuse("callbacks", "BodyCallbacks are not called by Contact Dynamics.");
#endif
	if (!exactAsphericalRot) refuse("exactAsphericalRot=False", rotation);
	if (rotAlgorithm != RotAlgorithm::delValle2023) refuse("rotAlgorithm", rotation);
	if (normalizeEvery != 5000) refuse("normalizeEvery=" + std::to_string(normalizeEvery), rotation);
	if (niterOmelyan1998 != 3) refuse("niterOmelyan1998=" + std::to_string(niterOmelyan1998), rotation);
	if (kinSplit) refuse("kinSplit=True", "the kinetic energy is tracked as one term (\"kinetic\").");
	if (!dampGravity) refuse("dampGravity=False", "there is no numerical damping (damping is 0), so it has no effect.");
}

// Bad input is reported before anything moves.
void ContactDynamicsIntegrator::checkScene()
{
	const Real h = scene->dt;
	if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("O.dt=" + std::to_string(h) + ": Contact Dynamics needs a positive, finite time step.");
	if (damping != 0) throw std::invalid_argument("ContactDynamicsIntegrator.damping=" + std::to_string(damping) + ": must be 0 (CD needs no numerical damping).");
	if (!finite(gravity)) throw std::invalid_argument("ContactDynamicsIntegrator.gravity is not finite.");
	checkInheritedAttributes();
	postLoad(*this);
	scene->forces.sync();

	const size_t nb = scene->bodies->size();
	core.bodies.assign(nb, cd::Body());
	core.records.assign(nb, cd::BodyRecord());
	start.assign(nb, StartOfStep());
	mover.resize(nb);
	clumps.clear();
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const State& s = *b->state;
		const string who = "body #" + std::to_string(b->id);
		if (!finite(s.pos) || !finite(s.vel) || !finite(s.angVel))
			throw std::invalid_argument(who + " has a NaN or infinite position or velocity.");
		if (scene->isPeriodic && !b->isClump() && b->shape->getClassName() != "Sphere")
			throw std::invalid_argument(
			        who + " is a " + b->shape->getClassName()
			        + " in a periodic cell: Contact Dynamics handles spheres and clumps of spheres there (a wall, facet or box has no periodic image).");
		cd::Body&       sb = core.bodies[b->id];
		cd::BodyRecord& br = core.records[b->id];
		start[b->id]       = StartOfStep { s.pos, s.ori, true };
		mover[b->id]       = b->id;
		br.vi = sb.v = s.vel;
		br.wi = sb.w = s.angVel;
		if (b->isClumpMember()) { // moved with its clump: never an unknown of the solve
			checkClumpMember(*b, who);
			mover[b->id] = b->clumpId;
			continue;
		}
		if (b->isClump()) {
			if (static_cast<const Clump*>(b->shape.get())->members.empty()) throw std::invalid_argument(who + " is a clump without members.");
			clumps.push_back(b->id);
		}
		br.dynamic         = b->isDynamic();
		br.pv = br.pw = Vector3r::Zero();
		sb.invM.setZero();
		sb.invI.setZero();
		if (!br.dynamic) continue;
		for (int k = 0; k < 3; ++k) {
			if (!(s.blockedDOFs & State::axisDOF(k, false))) {
				if (!(s.mass > 0) || !std::isfinite(s.mass)) throw std::invalid_argument(who + " is dynamic but has mass=" + std::to_string(s.mass) + " (must be > 0).");
				sb.invM[k] = 1 / s.mass;
			}
		}
		Vector3r invIbody = Vector3r::Zero();
		bool     anyRot   = false;
		for (int k = 0; k < 3; ++k)
			if (!(s.blockedDOFs & State::axisDOF(k, true))) anyRot = true;
		if (anyRot) {
			for (int k = 0; k < 3; ++k) {
				if (!(s.inertia[k] > 0) || !std::isfinite(s.inertia[k]))
					throw std::invalid_argument(who + " is dynamic but has inertia[" + std::to_string(k) + "]=" + std::to_string(s.inertia[k]) + " (must be > 0).");
				invIbody[k] = 1 / s.inertia[k];
			}
			const Matrix3r R = s.ori.toRotationMatrix();
			sb.invI          = R * invIbody.asDiagonal() * R.transpose();
			if (invIbody[0] == invIbody[1] && invIbody[1] == invIbody[2] && !(s.blockedDOFs & State::DOF_ALL)) {
				sb.invI     = invIbody[0] * Matrix3r::Identity(); // exact, no rotation round-off
				br.isoInvI  = invIbody[0];
				br.isoInvM  = sb.invM[0];
			}
			for (int k = 0; k < 3; ++k)
				if (s.blockedDOFs & State::axisDOF(k, true)) {
					sb.invI.row(k).setZero();
					sb.invI.col(k).setZero();
				}
		}
	}
}

// Why interaction I cannot take part in the solve ("" when it can, or when it is skipped: two
// obstacles, a potential interaction).
std::string ContactDynamicsIntegrator::interactionProblem(const Interaction& I) const
{
	if (!I.functorCache.geomExists) {
		const auto& b1 = Body::byId(I.getId1(), scene);
		const auto& b2 = Body::byId(I.getId2(), scene);
		if (!(b1 && b1->isDynamic()) && !(b2 && b2->isDynamic())) return ""; // two obstacles never meet
		return "no geometry functor for bodies " + pairName(I.getId1(), I.getId2()) + " (shapes " + (b1 ? b1->shape->getClassName() : "?") + ", "
		        + (b2 ? b2->shape->getClassName() : "?")
		        + "): Contact Dynamics supports Sphere–Sphere, Wall–Sphere, Facet–Sphere and Box–Sphere (see yadecd.engines()).";
	}
	if (!I.isReal()) return "";
	const auto* phys = dynamic_cast<const CDPhys*>(I.phys.get());
	if (!phys || !dynamic_cast<const ScGeom*>(I.geom.get()))
		return "interaction " + pairName(I.getId1(), I.getId2()) + " has " + I.geom->getClassName() + "/" + I.phys->getClassName()
		        + ": ContactDynamicsIntegrator needs ScGeom and CDPhys (use Ip2_FrictMat_FrictMat_CDPhys and Law2_ScGeom_CDPhys_Coulomb).";
	const Real mu = phys->tangensOfFrictionAngle;
	if (!(mu >= 0) || !std::isfinite(mu))
		return "contact " + pairName(I.getId1(), I.getId2()) + " has friction coefficient " + std::to_string(mu)
		        + ": check the frictionAngle of both bodies' materials (must be in [0, pi/2)).";
	if (!(phys->en >= 0 && phys->en <= 1) || !(phys->et >= -1 && phys->et <= 1))
		return "contact " + pairName(I.getId1(), I.getId2()) + " has restitution en, et outside [0,1], [-1,1].";
	return "";
}

// Stage 1: every CD contact into the core's contact set, in the base sweep order: by height
// along −gravity, ties by body ids (a key of the state only: the interaction container's own order
// changes after O.load or an erase, and Gauss–Seidel depends on order).
void ContactDynamicsIntegrator::gatherContacts()
{
	// Pass 1: the contacts that take part (real, CDPhys/ScGeom, a dynamic body on one side), each
	// with its sort key, collected by each thread over its contiguous block of the container and
	// joined in thread order, which is the container's order for any thread count. A bad
	// interaction is only noted there (no exception may leave a parallel region) and the first one
	// in the container's order is named afterwards. Only the keys are sorted; the contact records,
	// which are large, are written once, in their final places (pass 2).
	struct Key {
		Real                           height;
		int                            b1, b2;
		const shared_ptr<Interaction>* I; // the container's element (the container does not change here)
	};
	const Vector3r up = gravity.squaredNorm() > 0 ? Vector3r(-gravity.normalized()) : Vector3r::UnitZ();
	InteractionContainer& container = *scene->interactions;
	const long            ni        = long(container.size());
#ifdef YADE_OPENMP
	const int nt = ni >= 4096 ? omp_get_max_threads() : 1;
#else
	const int nt = 1;
#endif
	std::vector<std::vector<Key>> parts(nt);
	std::vector<long>             firstBad(nt, ni);
#pragma omp parallel num_threads(nt) if (nt > 1)
	{
#ifdef YADE_OPENMP
		const int t = omp_get_thread_num();
#else
		const int t = 0;
#endif
		std::vector<Key>& part = parts[t];
		part.reserve(size_t(core.contacts.size() / nt + 64));
#pragma omp for schedule(static)
		for (long i = 0; i < ni; ++i) {
			const shared_ptr<Interaction>& I = container[i];
			if (!I->isReal() || !I->functorCache.geomExists) {
				if (!I->functorCache.geomExists && firstBad[t] == ni && !interactionProblem(*I).empty()) firstBad[t] = i;
				continue;
			}
			const int id1 = mover[I->getId1()], id2 = mover[I->getId2()];
			if (!core.records[id1].dynamic && !core.records[id2].dynamic) continue; // obstacles never exchange impulses
			if (firstBad[t] == ni && !interactionProblem(*I).empty()) {
				firstBad[t] = i;
				continue;
			}
			part.push_back(Key { up.dot(static_cast<const ScGeom*>(I->geom.get())->contactPoint), id1, id2, &I });
		}
	}
	const long bad = *std::min_element(firstBad.begin(), firstBad.end());
	if (bad < ni) throw std::invalid_argument(interactionProblem(*container[bad]));
	std::vector<Key> keys;
	for (auto& part : parts)
		keys.insert(keys.end(), part.begin(), part.end());
	// The base sweep order.
	const long        nc = long(keys.size());
	std::vector<long> order(nc);
	std::iota(order.begin(), order.end(), 0L);
	std::sort(order.begin(), order.end(), [&keys](long a, long b) {
		const Key &ka = keys[a], &kb = keys[b];
		if (ka.height != kb.height) return ka.height < kb.height;
		return ka.b1 < kb.b1 || (ka.b1 == kb.b1 && ka.b2 < kb.b2);
	});
	// Pass 2: contact k is the k-th in that order; links[k] its interaction (ContactInfo::origin = k).
	cd::ContactSet& set = core.contacts;
	set.clear();
	set.resize(size_t(nc)); // fresh records: every field at its default, as add() gave them
	links.resize(size_t(nc));
#pragma omp parallel for schedule(static) if (nc >= 2048)
	for (long k = 0; k < nc; ++k) { // every contact written by one thread: the same set for any thread count
		const Key&   key  = keys[order[k]];
		Interaction& I    = **key.I;
		const auto*  phys = static_cast<const CDPhys*>(I.phys.get());
		const auto*  geom = static_cast<const ScGeom*>(I.geom.get());
		cd::ContactInfo& c = set.info[k];
		c.b1     = key.b1;
		c.b2     = key.b2;
		c.origin = k;
		c.gapI   = -geom->penetrationDepth;
		c.refR   = math::min(geom->refR1, geom->refR2);
		c.height = key.height;
		// overlap the contact may keep: what it was born with, shrinking with the overlap
		const Real overlap = math::max(Real(0), geom->penetrationDepth);
		c.allowance        = std::isnan(phys->overlapAllowance) ? overlap : math::min(phys->overlapAllowance, overlap);
		c.en               = phys->en;
		c.et               = phys->et;
		c.approach         = phys->approachVelocity;
		c.warmStart        = phys->impulse;
		if (scene->isPeriodic && I.cellDist != Vector3i::Zero()) {
			c.shifted = true;
			c.shift   = imageShiftVelocity(I.cellDist);
		}
		set.state[k] = cd::ContactState { Vector3r::Zero(), phys->tangensOfFrictionAngle, phys->status, -1 };
		links[k] = *key.I;
	}
	nContacts = int(nc);
	memberLever.assign(links.size(), { Vector3r::Zero(), Vector3r::Zero() });
}

// Stage 2 (paper §II.3): q_m = q_i + h/2 u_i, for every body (kinematic ones included); clump
// members follow their clump.
void ContactDynamicsIntegrator::predictPositions()
{
	const Real h = scene->dt;
	for (const auto& b : *scene->bodies) {
		if (!b || b->isClumpMember()) continue;
		State& s = *b->state;
		s.pos += 0.5 * h * s.vel;
		rotate(s.ori, s.angVel, 0.5 * h);
	}
	moveClumpMembers();
}

// Periodic cells, the start of a step, as NewtonIntegrator does it (YADE's conventions: the scene
// has already moved the cell over this step with the velocity gradient of the step before):
// a velGrad set by the user (Cell.nextVelGrad) takes effect now; with homoDeform > 0 every body's
// velocity jumps by ΔL·x and its spin by the rotational part of ΔL (ΔL = velGrad − prevVelGrad),
// so that bodies follow the new mean field; homoDeform > 1 adds the convective term h·L_prev·v
// (v before the jump, as NewtonIntegrator) to the free velocities (computeFreeVelocities). A changing cell size tells the collider to run.
void ContactDynamicsIntegrator::startCellStep()
{
	cellMaxVelocitySq = 0;
	beforeJump.clear();
	if (!scene->isPeriodic) return;
	Cell& cell = *scene->cell;
	adoptCellFlip(cell);
	if (cell.velGradChanged || cell.nextVelGrad != Matrix3r::Zero()) {
		cell.velGrad        = cell.nextVelGrad;
		cell.velGradChanged = false;
		cell.nextVelGrad    = Matrix3r::Zero();
	}
	cellHomoDeform = cell.homoDeform;
	cellDVelGrad   = cell.velGrad - prevVelGrad;
	const Matrix3r R = 0.5 * (cellDVelGrad - cellDVelGrad.transpose());
	cellDSpin            = Vector3r(-R(1, 2), R(0, 2), -R(0, 1));
	if (!math::isnan(prevCellSize[0]) && prevCellSize != cell.getSize())
		cellMaxVelocitySq = (prevCellSize - cell.getSize()).squaredNorm() / math::pow(scene->dt, 2);
	if (!cellHomoDeform || cellDVelGrad == Matrix3r::Zero()) return;
	beforeJump.resize(scene->bodies->size());
	for (const auto& b : *scene->bodies) {
		if (!b || b->isClumpMember()) continue; // members follow their clump
		State&          s  = *b->state;
		cd::Body&       sb = core.bodies[b->id];
		cd::BodyRecord& br = core.records[b->id];
		beforeJump[b->id]  = { s.vel, s.angVel };
		s.vel += cellDVelGrad * s.pos;
		s.angVel += cellDSpin;
		br.vi = sb.v = s.vel;
		br.wi = sb.w = s.angVel;
	}
	for (int id : clumps) {
		Clump::moveMembers<NewtonIntegrator>(Body::byId(id, scene), scene, nullptr);
		for (const auto& m : static_cast<const Clump*>(Body::byId(id, scene)->shape.get())->members) {
			core.records[m.first].vi = Body::byId(m.first, scene)->state->vel;
			core.records[m.first].wi = Body::byId(m.first, scene)->state->angVel;
		}
	}
}

// A flippable cell (Cell.flipFlippable) is flipped by the scene's prologue right after it moved:
// hSize becomes (I + hL)·H·F for an integer matrix F (a more compact base of the same lattice;
// H is the cell at the end of the step before), every interaction's cellDist is re-expressed in
// the new base, and Cell::postLoad sets prevHSize = hSize and the cache of intrShiftVel to
// L·hSize. For that step the cell's prevHSize is then one step ahead of the step's start (an
// image at the start and the middle of the step off by h·L·H·cellDist, the shift velocity by
// h·L²·H·cellDist). Here a flip is recognised from the cell this engine left at the end of the
// step before (H⁻¹·hSize rounds to F ≠ I), prevHSize is set to H·F (the step's start, in the new
// base), and the shift velocity of the step is L·H·F·cellDist with the L that moved the cell.
void ContactDynamicsIntegrator::adoptCellFlip(Cell& cell)
{
	cellFlipped = false;
	if (!hasPrevCellHSize) return;
	const Matrix3r G = prevCellHSize.inverse() * cell.hSize; // I + O(hL) without a flip
	Matrix3r       F;
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			F(i, j) = std::round(G(i, j));
	// a flip is unimodular and leaves only one step's deformation; anything else (the user set
	// hSize between steps, which YADE's postLoad already made the step's start) is not a flip
	if (F == Matrix3r::Identity() || math::abs(math::abs(F.determinant()) - 1) > 0.5 || (G - F).cwiseAbs().maxCoeff() > 0.25) return;
	cell.prevHSize = prevCellHSize * F;
	cellFlipped    = true;
}

// The velocity of body 2's periodic image relative to body 2 (Cell.intrShiftVel, but for the
// step of a flip: adoptCellFlip).
Vector3r ContactDynamicsIntegrator::imageShiftVelocity(const Vector3i& cellDist) const
{
	const Cell& cell = *scene->cell;
	if (!cellFlipped) return cell.intrShiftVel(cellDist);
	return prevVelGrad * cell.prevHSize * cellDist.cast<Real>();
}

// Periodic cells, the end of a step: the velocity gradient of this step becomes the previous one.
void ContactDynamicsIntegrator::endCellStep()
{
	if (!scene->isPeriodic) return;
	prevCellSize     = scene->cell->getSize();
	prevCellHSize    = scene->cell->hSize;
	hasPrevCellHSize = true;
	prevVelGrad = scene->cell->prevVelGrad = scene->cell->velGrad;
}

// The shift of body 2's periodic image for an interaction: Cell.hSize·cellDist, with the cell of
// the step's middle (q_m) or of its start (q_i). Zero outside periodic cells.
Vector3r ContactDynamicsIntegrator::imageShift(const Interaction& I, bool midStep) const
{
	if (!scene->isPeriodic || I.cellDist == Vector3i::Zero()) return Vector3r::Zero();
	const Cell&    cell = *scene->cell;
	const Matrix3r H    = midStep ? Matrix3r(0.5 * (cell.prevHSize + cell.hSize)) : cell.prevHSize;
	return H * I.cellDist.cast<Real>();
}

// Members of every clump to the clump's position, orientation and velocity (rigidly, as YADE's
// Clump::moveMembers places them for NewtonIntegrator).
void ContactDynamicsIntegrator::moveClumpMembers()
{
	for (int id : clumps)
		Clump::moveMembers<NewtonIntegrator>(Body::byId(id, scene), scene, nullptr);
}

// A clump member must be a sphere (the contact functors are the spheres'); the clump carries
// its mass and inertia, so the member's own are not read.
void ContactDynamicsIntegrator::checkClumpMember(const Body& b, const string& who)
{
	const auto& clump = Body::byId(b.clumpId, scene);
	if (!clump || !clump->isClump())
		throw std::invalid_argument(who + " is a clump member whose clump #" + std::to_string(b.clumpId) + " does not exist.");
	if (b.shape->getClassName() != "Sphere")
		throw std::invalid_argument(
		        who + " is a member of clump #" + std::to_string(b.clumpId) + " but a " + b.shape->getClassName()
		        + ": Contact Dynamics handles clumps of spheres only.");
}

// Stage 3: contact frames and gaps at q_m, from the same Ig2 functor that made the contact.
void ContactDynamicsIntegrator::updateContactFrames()
{
	const long nc = long(core.contacts.size());
#pragma omp parallel for schedule(static) if (nc >= 2048)
	for (long k = 0; k < nc; ++k) { // contacts are independent here: any thread count gives the same frames
		cd::ContactInfo&               c  = core.contacts.info[k];
		const shared_ptr<Interaction>& I  = links[c.origin];
		const auto&                    b1 = Body::byId(I->getId1(), scene); // the touching bodies (clump members included)
		const auto&                    b2 = Body::byId(I->getId2(), scene);
		ScGeom*                        g  = static_cast<ScGeom*>(I->geom.get());
		const Vector3r                 ni = g->normal, Ci = g->contactPoint; // at q_i
		const Vector3r                 shiftM = imageShift(*I, true); // body 2's periodic image (0 outside periodic cells)
		I->functorCache.geom->go(b1->shape, b2->shape, *b1->state, *b2->state, shiftM, /*force*/ false, I);
		Vector3r n = g->normal;
		// lever arms from the bodies the solver moves (a clump's centre of mass for its members;
		// body 2's image for a contact across a periodic boundary)
		c.c1       = g->contactPoint - Body::byId(c.b1, scene)->state->pos;
		c.c2       = g->contactPoint - (Body::byId(c.b2, scene)->state->pos + shiftM);
		c.gapM     = -g->penetrationDepth;
		// A grain fast enough to move more than its radius in half a step can put its centre
		// past an obstacle's centre or plane at q_m; the geometry there is then meaningless (a
		// flipped normal). Keep the q_i frame and predict the gap linearly instead.
		if (n.dot(ni) < 0.5 || -c.gapM > c.refR) {
			const cd::BodyRecord &s1 = core.records[c.b1], &s2 = core.records[c.b2];
			const Vector3r        c1 = Ci - start[c.b1].pos, c2 = Ci - (start[c.b2].pos + imageShift(*I, false));
			const Real            UiN = ni.dot((s2.vi + s2.wi.cross(c2)) - (s1.vi + s1.wi.cross(c1)) + c.shift);
			n                         = ni;
			c.c1                      = c1;
			c.c2                      = c2;
			c.gapM                    = c.gapI + 0.5 * scene->dt * UiN;
			g->normal                 = ni;
			g->contactPoint           = Ci + 0.5 * scene->dt * 0.5 * (s1.vi + s2.vi);
			g->penetrationDepth       = -c.gapM;
		}
		c.point           = g->contactPoint;
		memberLever[c.origin] = { g->contactPoint - b1->state->pos, g->contactPoint - (b2->state->pos + shiftM) };
		const Vector3r t1 = orthogonalUnit(n);
		c.frame.row(0)    = n;
		c.frame.row(1)    = t1;
		c.frame.row(2)    = n.cross(t1);
	}
}

// Stage 4: u_free = u_i + h M⁻¹ (F + m g), F from O.forces (user forces, GravityEngine...).
// Gravity is applied on unblocked translational axes only, as NewtonIntegrator does.
void ContactDynamicsIntegrator::computeFreeVelocities()
{
	const Real h = scene->dt;
	for (const auto& b : *scene->bodies) {
		if (!b || !core.records[b->id].dynamic) continue;
		cd::Body& sb = core.bodies[b->id];
		Vector3r  F  = scene->forces.getForce(b->id);
		Vector3r  T  = scene->forces.getTorque(b->id);
		if (b->isClump()) static_cast<Clump*>(b->shape.get())->addForceTorqueFromMembers(b->state.get(), scene, F, T);
		// the convective term, NewtonIntegrator's h·L_prev·v with v before this step's jump ΔL·x
		if (scene->isPeriodic && cellHomoDeform > 1)
			sb.v += h * prevVelGrad * (beforeJump.empty() ? core.records[b->id].vi : beforeJump[b->id].first);
		for (int k = 0; k < 3; ++k)
			if (sb.invM[k] > 0) sb.v[k] += h * (F[k] * sb.invM[k] + gravity[k]);
		sb.w += h * sb.invI * T;
	}
}

// The core's input of this step to problemFile (then cleared), for the core tests and benchmark.
void ContactDynamicsIntegrator::writeProblemFile()
{
	std::ofstream f(problemFile);
	if (f) cd::writeProblem(f, core, params());
	if (!f) throw std::invalid_argument("ContactDynamicsIntegrator.problemFile='" + problemFile + "': cannot be written.");
	problemFile.clear();
}

// Stage 5: the core's assembly of the local problems (Delassus blocks, law offsets, kernels).
void ContactDynamicsIntegrator::assembleLocalProblems() { core.assemble(params()); }

// Stage 6: the core's Gauss–Seidel solve; its statistics become this engine's attributes.
void ContactDynamicsIntegrator::solveImpulses()
{
	cd::SolveStats st = core.solve(params());
	iterations        = st.iterations;
	residual          = st.residual;
	converged         = st.converged;
	nSticking         = st.nSticking;
	nSliding          = st.nSliding;
	nStatusChanges    = st.nStatusChanges;
	nInterface        = st.nInterface;
	nColours          = st.nColours;
	residualHistory.swap(st.residualHistory);
	if (!converged) {
		++nUnconverged;
		if (warnUnconverged)
			LOG_WARN(
			        "iter " << scene->iter << ": Gauss–Seidel stopped after maxIter=" << maxIter << " sweeps with residual " << residual
			                << " > tolerance=" << tolerance << " (" << core.contacts.size() << " contacts). Counted in nUnconverged.");
	}
}

// Stage 7: the core's position correction (pseudo-velocities in core.records).
void ContactDynamicsIntegrator::correctPositions()
{
	const cd::CorrectionStats st = core.correct(params());
	projectionIterations         = st.iterations;
	maxCorrectedOverlap          = st.maxOverlap;
}

// Stage 8: q_f = q_m + h/2 (u_f + ũ), with u_f written to the bodies. Kinematic bodies and
// blocked DOFs keep their imposed velocity. NaNs are caught here, before anything is stored.
void ContactDynamicsIntegrator::updatePositions()
{
	const Real h = scene->dt;
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const cd::Body&       sb = core.bodies[b->id];
		const cd::BodyRecord& br = core.records[b->id];
		if (!finite(sb.v) || !finite(sb.w) || !finite(br.pv) || !finite(br.pw))
			throw std::runtime_error("iter " + std::to_string(scene->iter) + ": body #" + std::to_string(b->id) + " got a NaN velocity in the Contact Dynamics step.");
	}
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const cd::Body&       sb = core.bodies[b->id];
		const cd::BodyRecord& br = core.records[b->id];
		State&                s  = *b->state;
		if (br.dynamic) {
			s.vel    = sb.v;
			s.angVel = sb.w;
		}
		if (b->isClumpMember()) continue;
		s.pos += 0.5 * h * (s.vel + br.pv);
		rotate(s.ori, s.angVel + br.pw, 0.5 * h);
	}
	moveClumpMembers();
}

void ContactDynamicsIntegrator::restoreStartOfStep()
{
	for (const auto& b : *scene->bodies) {
		if (!b || !start[b->id].active) continue;
		b->state->pos    = start[b->id].pos;
		b->state->ori    = start[b->id].ori;
		b->state->vel    = core.records[b->id].vi;
		b->state->angVel = core.records[b->id].wi;
		if (size_t(b->id) < beforeJump.size() && !b->isClumpMember()) { // undo a periodic cell's velocity jump
			b->state->vel    = beforeJump[b->id].first;
			b->state->angVel = beforeJump[b->id].second;
		}
	}
	for (int id : clumps)
		Clump::moveMembers<NewtonIntegrator>(Body::byId(id, scene), scene, nullptr);
}

// Stage 9: impulses (warm start) and forces into CDPhys, contact forces into O.forces, energy,
// and the collider's hint (NewtonIntegrator::maxVelocitySq, as NewtonIntegrator sets it).
void ContactDynamicsIntegrator::storeResults()
{
	const Real h = scene->dt;
	const cd::ContactSet& set = core.contacts;
	const long            nc  = long(set.size());
#pragma omp parallel for schedule(static) if (nc >= 2048)
	for (long k = 0; k < nc; ++k) { // each contact writes its own CDPhys
		const cd::ContactInfo& c    = set.info[k];
		const Vector3r&        r    = set.state[k].r;
		auto*                  phys = static_cast<CDPhys*>(links[c.origin]->phys.get());
		phys->impulse               = c.frame.transpose() * r;
		phys->status                = set.state[k].status;
		phys->overlapAllowance      = c.allowance;
		phys->normalForce           = c.frame.row(0).transpose() * (r[0] / h);
		phys->shearForce            = (c.frame.row(1).transpose() * r[1] + c.frame.row(2).transpose() * r[2]) / h;
		// a contact that landed keeps its approach velocity for the next step's restitution law
		const bool landed      = c.gapM > 0 && r[0] > 0 && (phys->en > 0 || phys->et != 0);
		phys->approachVelocity = landed ? Vector3r(c.frame.transpose() * c.Ui) : Vector3r::Zero();
	}
	if (scene->trackEnergy) trackEnergy(); // O.forces still holds only the external forces here
	for (size_t k = 0; k < set.size(); ++k) {
		const cd::ContactInfo& c = set.info[k];
		const Vector3r         P = c.frame.transpose() * set.state[k].r;
		scene->forces.addForce(c.b2, P / h);
		scene->forces.addTorque(c.b2, c.c2.cross(P) / h);
		scene->forces.addForce(c.b1, -P / h);
		scene->forces.addTorque(c.b1, -c.c1.cross(P) / h);
		// a clump member also gets its own contact force, about its own centre (YADE's
		// utilities and exporters read members; the clump holds the sum, as after NewtonIntegrator)
		const Interaction& I = *links[c.origin];
		if (I.getId2() != c.b2) {
			scene->forces.addForce(I.getId2(), P / h);
			scene->forces.addTorque(I.getId2(), memberLever[c.origin].second.cross(P) / h);
		}
		if (I.getId1() != c.b1) {
			scene->forces.addForce(I.getId1(), -P / h);
			scene->forces.addTorque(I.getId1(), -memberLever[c.origin].first.cross(P) / h);
		}
	}
	scene->forces.sync();

	// collider hint: > 1 when some body left its bound's sweep distance (or a periodic cell changed size)
	maxVelocitySq = cellMaxVelocitySq;
#ifdef YADE_OPENMP
	std::fill(threadMaxVelocitySq.begin(), threadMaxVelocitySq.end(), Real(0));
#endif
	const long nb = long(scene->bodies->size());
#pragma omp parallel for schedule(static) if (nb >= 4096)
	for (long id = 0; id < nb; ++id) { // a maximum per thread (NewtonIntegrator's), then the maximum of those
		const shared_ptr<Body>& b = (*scene->bodies)[id];
		if (b) saveMaximaDisplacement(b);
	}
#ifdef YADE_OPENMP
	for (const Real& m : threadMaxVelocitySq)
		maxVelocitySq = math::max(maxVelocitySq, m);
#endif
}

// Energy balance of the step, exact for the midpoint scheme: with ū = (u_i + u_f)/2,
// ΔKE = ū·(h F_ext + h m g) + Σ_α r_α·Ū_α − Σ_kinematic ū_b·P_b, and q_f − q_i = h ū (+ the
// pseudo-displacement of the position correction, booked as "positionCorrection").
// Names follow YADE's: every term is minus a work, so O.energy.total() stays constant.
void ContactDynamicsIntegrator::trackEnergy()
{
	const Real h             = scene->dt;
	Real       contactDissip = 0, kinematicWork = 0;
	const cd::ContactSet& set = core.contacts;
	for (size_t k = 0; k < set.size(); ++k) {
		const cd::ContactInfo& c = set.info[k];
		contactDissip -= set.state[k].r.dot(0.5 * (c.Ui + core.localVelocity(long(k))));
		const Vector3r P = c.frame.transpose() * set.state[k].r;
		for (int side = 0; side < 2; ++side) {
			const int             id = side ? c.b2 : c.b1;
			const cd::BodyRecord& br = core.records[id];
			if (br.dynamic) continue;
			const cd::Body& sb = core.bodies[id];
			const Vector3r    Pb = side ? P : Vector3r(-P);
			const Vector3r    cb = side ? c.c2 : c.c1;
			kinematicWork += Pb.dot(0.5 * (br.vi + sb.v)) + cb.cross(Pb).dot(0.5 * (br.wi + sb.w));
		}
	}
	Real kinetic = 0, gravWork = 0, extWork = 0, posCorr = 0;
	for (const auto& b : *scene->bodies) {
		if (!b || !core.records[b->id].dynamic) continue;
		const cd::Body&       sb = core.bodies[b->id];
		const cd::BodyRecord& br = core.records[b->id];
		const State&          s  = *b->state;
		const Matrix3r    R  = s.ori.toRotationMatrix();
		kinetic += 0.5 * s.mass * s.vel.squaredNorm() + 0.5 * s.angVel.dot(R * s.inertia.asDiagonal() * R.transpose() * s.angVel);
		Vector3r g = gravity;
		for (int k = 0; k < 3; ++k)
			if (sb.invM[k] == 0) g[k] = 0;
		gravWork -= s.mass * g.dot(s.pos - start[b->id].pos);
		posCorr += s.mass * g.dot(0.5 * h * br.pv);
		Vector3r F = scene->forces.getForce(b->id), T = scene->forces.getTorque(b->id);
		if (b->isClump()) static_cast<Clump*>(b->shape.get())->addForceTorqueFromMembers(&s, scene, F, T); // members' external forces
		extWork -= h * (F.dot(0.5 * (br.vi + sb.v)) + T.dot(0.5 * (br.wi + sb.w)));
	}
	scene->energy->add(kinetic, "kinetic", kinEnergyIx, /*reset*/ true);
	scene->energy->add(gravWork, "gravWork", fieldWorkIx, false);
	scene->energy->add(contactDissip, "contactDissip", contactDissipIx, false);
	if (extWork != 0) scene->energy->add(extWork, "externalWork", extWorkIx, false);
	if (kinematicWork != 0) scene->energy->add(kinematicWork, "kinematicWork", kinematicWorkIx, false);
	if (posCorr != 0) scene->energy->add(posCorr, "positionCorrection", posCorrIx, false);
}

} // namespace yade
