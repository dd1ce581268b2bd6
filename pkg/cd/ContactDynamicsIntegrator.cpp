// Contact Dynamics plugin for YADE: Moreau's time-stepping integrator (see the header for the
// architecture, the contact law and the sign conventions).
#include "ContactDynamicsIntegrator.hpp"
#include "core/LocalSolver.hpp"
#include "CDPhys.hpp"
#include <core/Clump.hpp>
#include <core/Scene.hpp>
#include <pkg/dem/ScGeom.hpp>

#include <algorithm>
#include <sstream>

namespace yade {

YADE_PLUGIN((ContactDynamicsIntegrator));
CREATE_LOGGER(ContactDynamicsIntegrator);

// The sweep's innermost helpers are member functions with vague linkage: in a -fPIC shared
// library GCC would call them through the PLT (they are interposable) instead of inlining them,
// which made the sweep 14% slower (measured with perf and solver_bench.py). Force them inline.
#define CD_HOT inline __attribute__((always_inline))

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
	// Cross-product matrix [c]x, so that [c]x p = c × p.
	Matrix3r skew(const Vector3r& c)
	{
		Matrix3r m;
		m << 0, -c[2], c[1], c[2], 0, -c[0], -c[1], c[0], 0;
		return m;
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

void ContactDynamicsIntegrator::postLoad(ContactDynamicsIntegrator&)
{
	auto bad = [](const std::string& what) { throw std::invalid_argument("ContactDynamicsIntegrator." + what); };
	if (!(tolerance > 0)) bad("tolerance=" + std::to_string(tolerance) + ": must be a positive number.");
	if (maxIter < 1) bad("maxIter=" + std::to_string(maxIter) + ": must be at least 1.");
	if (checkEvery < 1) bad("checkEvery=" + std::to_string(checkEvery) + ": must be at least 1.");
	if (!(alertRatio >= 0)) bad("alertRatio=" + std::to_string(alertRatio) + ": must be ≥ 0.");
	if (!(alertSpeedFactor >= 1)) bad("alertSpeedFactor=" + std::to_string(alertSpeedFactor) + ": must be ≥ 1, or contacts closing within a step are missed.");
	if (!(positionTolerance > 0)) bad("positionTolerance=" + std::to_string(positionTolerance) + ": must be a positive number.");
	if (!(relaxation > 0 && relaxation < 2)) bad("relaxation=" + std::to_string(relaxation) + ": must lie in (0, 2).");
	if (sweepOrder < 0 || sweepOrder > 5) bad("sweepOrder=" + std::to_string(sweepOrder) + ": must be 0, 1, 2, 3, 4 or 5.");
	if (slabs < 1 || slabs > 64) bad("slabs=" + std::to_string(slabs) + ": must lie in 1..64.");
	if (maxProjectionIter < 1) bad("maxProjectionIter=" + std::to_string(maxProjectionIter) + ": must be at least 1.");
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
	if (!(mu >= 0)) throw std::invalid_argument("solveLocal: mu must be ≥ 0.");
	if (W.ldlt().info() != Eigen::Success || !(W.diagonal().minCoeff() > 0)) throw std::invalid_argument("solveLocal: W must be symmetric positive definite.");
	Vector3r r = Vector3r::Zero();
	const int status = int(cd::solveLocal(W, b, mu, r));
	return boost::python::make_tuple(r, status);
}

// The law's Delassus matrix W (Ũ = W r + q over all contacts) as COO triplets, blocks
// A_a F_a K_ab F_bᵀ with K_ab = s_a s_b (diag(1/m) − [c_a]x I⁻¹ [c_b]x) summed over the bodies
// contacts a and b share (s = +1 on body 2, −1 on body 1). Entries of one block position may
// come twice (a contact with itself, through both bodies): they are to be summed.
void ContactDynamicsIntegrator::delassusTriplets(std::vector<long>& rows, std::vector<long>& cols, std::vector<double>& vals) const
{
	std::vector<std::vector<std::pair<int, int>>> incident(bodies.size()); // (contact, side)
	for (size_t a = 0; a < contacts.size(); ++a) {
		if (records[contacts[a].b1].dynamic) incident[contacts[a].b1].push_back({ int(a), 0 });
		if (records[contacts[a].b2].dynamic) incident[contacts[a].b2].push_back({ int(a), 1 });
	}
	for (size_t id = 0; id < bodies.size(); ++id) {
		const SolverBody& body = bodies[id];
		for (const auto& [a, sa] : incident[id])
			for (const auto& [b, sb] : incident[id]) {
				const SolverContact &ca = contacts[a], &cb = contacts[b];
				const Real           sign = (sa ? 1 : -1) * (sb ? 1 : -1);
				const Matrix3r       K    = sign * (Matrix3r(body.invM.asDiagonal()) - skew(sa ? ca.c2 : ca.c1) * body.invI * skew(sb ? cb.c2 : cb.c1));
				const Matrix3r       Wab  = ca.A.asDiagonal() * (ca.frame * K * cb.frame.transpose());
				for (int i = 0; i < 3; ++i)
					for (int j = 0; j < 3; ++j) {
						rows.push_back(3 * a + i);
						cols.push_back(3 * b + j);
						vals.push_back(double(Wab(i, j)));
					}
			}
	}
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
	std::vector<double> vals, q(3 * contacts.size()), mu, r;
	delassusTriplets(rows, cols, vals);
	for (size_t a = 0; a < contacts.size(); ++a) {
		const SolverContact& c    = contacts[a];
		const Vector3r       Ulaw = c.A.cwiseProduct(localVelocity(c) + c.s); // the law's velocity at the solution
		for (int i = 0; i < 3; ++i) {
			q[3 * a + i] = double(Ulaw[i]);
			r.push_back(double(c.r[i]));
		}
		mu.push_back(double(c.mu));
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

Vector3r ContactDynamicsIntegrator::pyResidual(const Vector3r& r, const Vector3r& U, Real mu, Real rho) { return cd::naturalMapResidual(r, U, mu, rho); }

// ----------------------------------------------------------------------------- the step

void ContactDynamicsIntegrator::action()
{
	timingDeltas->start();
	checkScene();
	gatherContacts();
	timingDeltas->checkpoint("gatherContacts");
	predictPositions();
	try {
		updateContactFrames();
		timingDeltas->checkpoint("updateContactFrames");
		computeFreeVelocities();
		assembleLocalProblems();
		timingDeltas->checkpoint("assembleLocalProblems");
		solveImpulses();
		timingDeltas->checkpoint("solveImpulses");
		correctPositions();
		timingDeltas->checkpoint("correctPositions");
		updatePositions();
	} catch (...) {
		restoreStartOfStep(); // a failed step leaves the scene as it found it
		throw;
	}
	storeResults();
	timingDeltas->checkpoint("storeResults");
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
	if (scene->isPeriodic) throw std::invalid_argument("ContactDynamicsIntegrator: periodic cells are not supported.");
	if (damping != 0) throw std::invalid_argument("ContactDynamicsIntegrator.damping=" + std::to_string(damping) + ": must be 0 (CD needs no numerical damping).");
	if (!finite(gravity)) throw std::invalid_argument("ContactDynamicsIntegrator.gravity is not finite.");
	checkInheritedAttributes();
	postLoad(*this);
	scene->forces.sync();

	bodies.assign(scene->bodies->size(), SolverBody());
	records.assign(scene->bodies->size(), BodyRecord());
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const State& s = *b->state;
		const string who = "body #" + std::to_string(b->id);
		if (b->isClump() || b->isClumpMember()) throw std::invalid_argument(who + " is (in) a clump: clumps are not supported by ContactDynamicsIntegrator.");
		if (!finite(s.pos) || !finite(s.vel) || !finite(s.angVel))
			throw std::invalid_argument(who + " has a NaN or infinite position or velocity.");
		SolverBody& sb = bodies[b->id];
		BodyRecord& br = records[b->id];
		br.active      = true;
		br.dynamic     = b->isDynamic();
		br.vi = sb.v = s.vel;
		br.wi = sb.w = s.angVel;
		br.pv = br.pw = Vector3r::Zero();
		br.qi         = s.pos;
		br.oi         = s.ori;
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

// Stage 1: copy every CD contact into the flat array, in a fixed order (by height along −gravity,
// ties by (id1, id2); by ids only for sweepOrder 0): the interaction container's own order changes
// after O.load or an erase, and Gauss–Seidel depends on order.
void ContactDynamicsIntegrator::gatherContacts()
{
	contacts.clear();
	for (const auto& I : *scene->interactions) {
		if (!I->functorCache.geomExists) {
			const auto& b1 = Body::byId(I->getId1(), scene);
			const auto& b2 = Body::byId(I->getId2(), scene);
			if (!(b1 && b1->isDynamic()) && !(b2 && b2->isDynamic())) continue; // two obstacles never meet
			throw std::invalid_argument(
			        "no geometry functor for bodies " + pairName(I->getId1(), I->getId2()) + " (shapes " + (b1 ? b1->shape->getClassName() : "?") + ", "
			        + (b2 ? b2->shape->getClassName() : "?")
			        + "): Contact Dynamics supports Sphere–Sphere, Wall–Sphere and Facet–Sphere (see yadecd.engines()).");
		}
		if (!I->isReal()) continue;
		if (!records[I->getId1()].dynamic && !records[I->getId2()].dynamic) continue; // obstacles never exchange impulses
		auto* phys = dynamic_cast<CDPhys*>(I->phys.get());
		auto* geom = dynamic_cast<ScGeom*>(I->geom.get());
		if (!phys || !geom)
			throw std::invalid_argument(
			        "interaction " + pairName(I->getId1(), I->getId2()) + " has " + I->geom->getClassName() + "/" + I->phys->getClassName()
			        + ": ContactDynamicsIntegrator needs ScGeom and CDPhys (use Ip2_FrictMat_FrictMat_CDPhys and Law2_ScGeom_CDPhys_Coulomb).");
		const Real mu = phys->tangensOfFrictionAngle;
		if (!(mu >= 0) || !std::isfinite(mu))
			throw std::invalid_argument(
			        "contact " + pairName(I->getId1(), I->getId2()) + " has friction coefficient " + std::to_string(mu)
			        + ": check the frictionAngle of both bodies' materials (must be in [0, pi/2)).");
		if (!(phys->en >= 0 && phys->en <= 1) || !(phys->et >= -1 && phys->et <= 1))
			throw std::invalid_argument("contact " + pairName(I->getId1(), I->getId2()) + " has restitution en, et outside [0,1], [-1,1].");
		SolverContact c;
		c.I      = I;
		c.b1     = I->getId1();
		c.b2     = I->getId2();
		c.mu     = mu;
		c.gapI   = -geom->penetrationDepth;
		c.refR   = math::min(geom->refR1, geom->refR2);
		c.status = phys->status;
		// overlap the contact may keep: what it was born with, shrinking with the overlap
		const Real overlap = math::max(Real(0), geom->penetrationDepth);
		c.allowance        = std::isnan(phys->overlapAllowance) ? overlap : math::min(phys->overlapAllowance, overlap);
		contacts.push_back(c);
	}
	// Gauss–Seidel order: by height along −gravity (z without gravity), ties by ids; an upward
	// sweep carries a load change from the floor up the whole stack in one sweep (sweepOrder
	// 0 uses ids only). The key depends only on the state, so a saved and reloaded scene sweeps
	// in the same order.
	const Vector3r up = gravity.squaredNorm() > 0 ? Vector3r(-gravity.normalized()) : Vector3r::UnitZ();
	for (SolverContact& c : contacts)
		c.height = up.dot(static_cast<ScGeom*>(c.I->geom.get())->contactPoint);
	const bool byHeight = sweepOrder != 0;
	std::sort(contacts.begin(), contacts.end(), [byHeight](const SolverContact& a, const SolverContact& b) {
		if (byHeight && a.height != b.height) return a.height < b.height;
		return a.b1 < b.b1 || (a.b1 == b.b1 && a.b2 < b.b2);
	});
	nContacts = int(contacts.size());
}

// Stage 2 (paper §II.3): q_m = q_i + h/2 u_i, for every body (kinematic ones included).
void ContactDynamicsIntegrator::predictPositions()
{
	const Real h = scene->dt;
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		State& s = *b->state;
		s.pos += 0.5 * h * s.vel;
		rotate(s.ori, s.angVel, 0.5 * h);
	}
}

// Stage 3: contact frames and gaps at q_m, from the same Ig2 functor that made the contact.
void ContactDynamicsIntegrator::updateContactFrames()
{
	const long nc = long(contacts.size());
#pragma omp parallel for schedule(static) if (nc >= 2048)
	for (long k = 0; k < nc; ++k) { // contacts are independent here: any thread count gives the same frames
		SolverContact& c = contacts[k];
		const auto& b1 = Body::byId(c.b1, scene);
		const auto& b2 = Body::byId(c.b2, scene);
		ScGeom*        g  = static_cast<ScGeom*>(c.I->geom.get());
		const Vector3r ni = g->normal, Ci = g->contactPoint; // at q_i
		c.I->functorCache.geom->go(b1->shape, b2->shape, *b1->state, *b2->state, Vector3r::Zero(), /*force*/ false, c.I);
		Vector3r n = g->normal;
		c.c1       = g->contactPoint - b1->state->pos;
		c.c2       = g->contactPoint - b2->state->pos;
		c.gapM     = -g->penetrationDepth;
		// A grain fast enough to move more than its radius in half a step can put its centre
		// past an obstacle's centre or plane at q_m; the geometry there is then meaningless (a
		// flipped normal). Keep the q_i frame and predict the gap linearly instead.
		if (n.dot(ni) < 0.5 || -c.gapM > c.refR) {
			const BodyRecord &s1 = records[c.b1], &s2 = records[c.b2];
			const Vector3r    c1 = Ci - s1.qi, c2 = Ci - s2.qi;
			const Real        UiN = ni.dot((s2.vi + s2.wi.cross(c2)) - (s1.vi + s1.wi.cross(c1)));
			n                     = ni;
			c.c1                  = c1;
			c.c2                  = c2;
			c.gapM                = c.gapI + 0.5 * scene->dt * UiN;
			g->normal             = ni;
			g->contactPoint       = Ci + 0.5 * scene->dt * 0.5 * (s1.vi + s2.vi);
			g->penetrationDepth   = -c.gapM;
		}
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
		if (!b || !records[b->id].dynamic) continue;
		SolverBody&    sb = bodies[b->id];
		const Vector3r F  = scene->forces.getForce(b->id);
		const Vector3r T  = scene->forces.getTorque(b->id);
		for (int k = 0; k < 3; ++k)
			if (sb.invM[k] > 0) sb.v[k] += h * (F[k] * sb.invM[k] + gravity[k]);
		sb.w += h * sb.invI * T;
	}
}

// Stage 5: per contact, W = F (K1 + K2) Fᵀ with K_b = diag(1/m_b) − [c_b]x I_b⁻¹ [c_b]x, the
// start-of-step local velocity U_i, and the law's scaling A and offset s (see the header).
void ContactDynamicsIntegrator::assembleLocalProblems()
{
	const Real h  = scene->dt;
	const long nc = long(contacts.size());
	hot.resize(nc);
	qShare.resize(nc); // each contact's share of ‖q‖², summed below in a fixed order
#pragma omp parallel for schedule(static) if (nc >= 2048)
	for (long k = 0; k < nc; ++k) { // contacts are independent here: any thread count gives the same blocks
		SolverContact&    c  = contacts[k];
		const SolverBody& b1 = bodies[c.b1];
		const SolverBody& b2 = bodies[c.b2];
		const BodyRecord& r1 = records[c.b1];
		const BodyRecord& r2 = records[c.b2];
		const Matrix3r    S1 = skew(c.c1), S2 = skew(c.c2);
		const Matrix3r    K  = Matrix3r(b1.invM.asDiagonal()) - S1 * b1.invI * S1 + Matrix3r(b2.invM.asDiagonal()) - S2 * b2.invI * S2;
		c.W                  = c.frame * K * c.frame.transpose();
		qShare[k]            = 0;
		if (!(c.W(0, 0) > 0)) continue; // reported below, outside the parallel loop
		c.Ui       = c.frame * ((r2.vi + r2.wi.cross(c.c2)) - (r1.vi + r1.wi.cross(c.c1)));
		auto* phys = static_cast<CDPhys*>(c.I->phys.get());
		if (c.gapM > 0) { // open: the end-of-step gap g_m + h/2 U_N must stay ≥ 0
			c.A = Vector3r::Ones();
			c.s = Vector3r(2 * c.gapM / h, 0, 0);
		} else { // closed: Moreau's restitution mean; a contact that landed last step uses its approach velocity
			const Vector3r Ui = (phys->approachVelocity != Vector3r::Zero()) ? Vector3r(c.frame * phys->approachVelocity) : c.Ui;
			c.A               = Vector3r(1 / (1 + phys->en), 1 / (1 + phys->et), 1 / (1 + phys->et));
			c.s               = Vector3r(phys->en * Ui[0], phys->et * Ui[1], phys->et * Ui[2]);
		}
		c.Wlaw    = c.A.asDiagonal() * c.W;
		c.WlawInv = c.Wlaw.inverse();
		c.r       = c.frame * phys->impulse; // warm start, re-expressed in the new frame
		buildSphereContact(size_t(k));
		// residual scale: free local velocities of the contacts that would close without an
		// impulse (q_N < 0); far gap contacts, whose offsets 2 g_m/h are large, do not dilute it
		const Vector3r q = c.A.cwiseProduct(localVelocity(c) + c.s);
		if (q[0] < 0) qShare[k] = q.squaredNorm();
	}
	qNorm = 0;
	for (long k = 0; k < nc; ++k) {
		const SolverContact& c = contacts[k];
		if (!(c.W(0, 0) > 0))
			throw std::invalid_argument("contact " + pairName(c.b1, c.b2) + " joins two bodies that cannot move: make one of them dynamic or remove the contact.");
		qNorm += qShare[k];
	}
	qNorm = math::sqrt(qNorm);
}

Vector3r ContactDynamicsIntegrator::localVelocity(const SolverContact& c) const
{
	const SolverBody& b1 = bodies[c.b1];
	const SolverBody& b2 = bodies[c.b2];
	return c.frame * ((b2.v + b2.w.cross(c.c2)) - (b1.v + b1.w.cross(c.c1)));
}

// The hot copy of contact k, when its geometry and bodies allow (see SphereContact).
void ContactDynamicsIntegrator::buildSphereContact(size_t k)
{
	const SolverContact& c = contacts[k];
	SphereContact&       h = hot[k];
	h.fast                 = false;
	if (!sphereFastPath) return;
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
			if (bodies[id].w != Vector3r::Zero()) return; // a rotating obstacle: general path
			invM[side] = invI[side] = 0;
		}
	}
	h.fast = true;
	h.n    = c.frame.row(0);
	h.t1   = c.frame.row(1);
	h.t2   = c.frame.row(2);
	h.l1 = lever[0], h.l2 = lever[1];
	h.m1 = invM[0], h.m2 = invM[1];
	h.k1 = invI[0] * lever[0], h.k2 = invI[1] * lever[1];
	const Real wn = h.m1 + h.m2, wt = wn + h.l1 * h.k1 + h.l2 * h.k2;
	h.Wd   = c.A.cwiseProduct(Vector3r(wn, wt, wt));
	h.A    = c.A;
	h.bias = c.A.cwiseProduct(c.s);
	h.r    = c.r;
	h.mu   = c.mu;
	h.wnn  = wn;
	h.b1 = c.b1, h.b2 = c.b2;
	h.status = c.status;
}

void ContactDynamicsIntegrator::syncHotContacts()
{
	for (size_t k = 0; k < contacts.size(); ++k)
		if (hot[k].fast) {
			contacts[k].r      = hot[k].r;
			contacts[k].status = hot[k].status;
		}
}

// Local velocity U of a SphereContact. With c_b = l_b n the rotation terms are l_b (w_b × n),
// whose local components are (0, w_b·t2, −w_b·t1).
CD_HOT Vector3r ContactDynamicsIntegrator::sphereVelocity(const SphereContact& c) const
{
	const SolverBody& B1 = bodies[c.b1];
	const SolverBody& B2 = bodies[c.b2];
	const Vector3r    dv = B2.v - B1.v;
	const Vector3r    om = c.l2 * B2.w - c.l1 * B1.w;
	return Vector3r(c.n.dot(dv), c.t1.dot(dv) + om.dot(c.t2), c.t2.dot(dv) - om.dot(c.t1));
}

// The impulse change dr (local frame) applied to both bodies; its moment about a centre is
// l_b (n × P) = l_b (dr_1 t2 − dr_2 t1).
CD_HOT void ContactDynamicsIntegrator::applySphereImpulse(const SphereContact& c, const Vector3r& dr)
{
	const Vector3r P = dr[0] * c.n + dr[1] * c.t1 + dr[2] * c.t2;
	const Vector3r x = dr[1] * c.t2 - dr[2] * c.t1;
	if (c.m2 > 0) { // obstacles are never written (a coloured sweep shares them between threads)
		SolverBody& B2 = bodies[c.b2];
		B2.v += c.m2 * P;
		B2.w += c.k2 * x;
	}
	if (c.m1 > 0) {
		SolverBody& B1 = bodies[c.b1];
		B1.v -= c.m1 * P;
		B1.w -= c.k1 * x;
	}
}

// One Gauss–Seidel update of a SphereContact; returns the impulse change.
CD_HOT Vector3r ContactDynamicsIntegrator::updateSphereContact(SphereContact& c, Real omega)
{
	const Vector3r b = c.A.cwiseProduct(sphereVelocity(c)) - c.Wd.cwiseProduct(c.r) + c.bias;
	Vector3r       r;
	c.status = int(cd::solveLocalDiagonal(c.Wd, b, c.mu, r));
	if (omega != 1 && c.status != int(cd::ContactStatus::Open)) r = cd::projectOnCone(c.r + omega * (r - c.r), c.mu);
	const Vector3r dr = r - c.r;
	applySphereImpulse(c, dr);
	c.r = r;
	return dr;
}

// One Gauss–Seidel update of any contact: its local velocity without its own impulse,
// b = U − W r, the exact local solve of Ũ = A(W r + b + s), the change applied to both bodies.
Vector3r ContactDynamicsIntegrator::updateGeneralContact(SolverContact& c, Real omega)
{
	const Vector3r U = localVelocity(c);
	const Vector3r b = c.A.cwiseProduct(U - c.W * c.r + c.s);
	Vector3r       r = c.r;
	c.status         = int(cd::solveLocal(c.Wlaw, c.WlawInv, b, c.mu, r));
	if (omega != 1 && c.status != int(cd::ContactStatus::Open)) r = cd::projectOnCone(c.r + omega * (r - c.r), c.mu);
	const Vector3r dr = r - c.r;
	applyImpulse(c, dr);
	c.r = r;
	return dr;
}

void ContactDynamicsIntegrator::applyImpulse(const SolverContact& c, const Vector3r& dr)
{
	const Vector3r P  = c.frame.transpose() * dr; // on body 2; −P on body 1
	SolverBody&    b1 = bodies[c.b1];
	SolverBody&    b2 = bodies[c.b2];
	if (records[c.b2].dynamic) { // obstacles are never written (see updateSphereContact)
		b2.v += b2.invM.cwiseProduct(P);
		b2.w += b2.invI * c.c2.cross(P);
	}
	if (records[c.b1].dynamic) {
		b1.v -= b1.invM.cwiseProduct(P);
		b1.w -= b1.invI * c.c1.cross(P);
	}
}

// Relative residual: sqrt(Σ|e_α|²)/‖q‖, e_α the natural-map residual in velocity units.
Real ContactDynamicsIntegrator::computeResidual()
{
	Real sum = 0;
	nSticking = nSliding = 0;
	for (size_t k = 0; k < contacts.size(); ++k) {
		Vector3r r, Ulaw;
		Real     rho, mu;
		int      status;
		if (hot[k].fast) {
			const SphereContact& c = hot[k];
			Ulaw = c.A.cwiseProduct(sphereVelocity(c)) + c.bias;
			r = c.r, rho = 1 / c.Wd[0], mu = c.mu, status = c.status;
		} else {
			const SolverContact& c = contacts[k];
			Ulaw = c.A.cwiseProduct(localVelocity(c) + c.s);
			r = c.r, rho = 1 / c.Wlaw(0, 0), mu = c.mu, status = c.status;
		}
		// ρ for the law's own block: the law sees Ũ = A U, so scale as 1/Wlaw_NN
		sum += cd::naturalMapResidual(r, Ulaw, mu, rho).squaredNorm();
		if (status == int(cd::ContactStatus::Sticking)) ++nSticking;
		if (status == int(cd::ContactStatus::Sliding)) ++nSliding;
	}
	const Real scale = qNorm > 0 ? qNorm : Real(1);
	return math::sqrt(sum) / scale;
}

// One Gauss–Seidel update of contact idx through its path; returns (W_NN |Δr|)², counts a
// status change in *changed.
CD_HOT Real ContactDynamicsIntegrator::updateContact(long idx, Real omega, bool& changed)
{
	if (hot[idx].fast) {
		SphereContact& c      = hot[idx];
		const int      before = c.status;
		const Real     d      = updateSphereContact(c, omega).squaredNorm() * c.wnn * c.wnn;
		changed               = c.status != before;
		return d;
	}
	SolverContact& c      = contacts[idx];
	const int      before = c.status;
	const Real     d      = updateGeneralContact(c, omega).squaredNorm() * c.W(0, 0) * c.W(0, 0);
	changed               = c.status != before;
	return d;
}

// Contacts [begin, end) updated in turn: returns Σ(W_NN|Δr|)², adds status changes to nChanged.
CD_HOT Real ContactDynamicsIntegrator::sweepRange(long begin, long end, Real omega, int& nChanged)
{
	Real change = 0;
	for (long k = begin; k < end; ++k) {
		bool changed;
		change += updateContact(k, omega, changed);
		nChanged += changed;
	}
	return change;
}

// A sequential sweep in the contacts' order (up) or the reverse.
Real ContactDynamicsIntegrator::orderedSweep(Real omega, bool up)
{
	const long nc  = long(contacts.size());
	nStatusChanges = 0;
	if (up) return sweepRange(0, nc, omega, nStatusChanges);
	Real change = 0;
	for (long k = nc - 1; k >= 0; --k) {
		bool changed;
		change += updateContact(k, omega, changed);
		nStatusChanges += changed;
	}
	return change;
}

// Store contacts (and their hot copies) in the given order: contacts[j] ← contacts[order[j]].
void ContactDynamicsIntegrator::permuteContacts(const std::vector<long>& order)
{
	std::vector<SolverContact> sorted;
	std::vector<SphereContact> hotSorted;
	sorted.reserve(contacts.size());
	hotSorted.reserve(contacts.size());
	for (long k : order) {
		sorted.push_back(std::move(contacts[k]));
		hotSorted.push_back(hot[k]);
	}
	contacts.swap(sorted);
	hot.swap(hotSorted);
}

// Greedy colouring in the contacts' (height) order, then the contacts reordered by colour: the smallest colour not yet taken by a
// contact of either dynamic body (obstacles never conflict: nothing writes them). Contacts of
// one colour share no dynamic body, so their updates commute. Colours past 63 form one last
// group swept sequentially.
void ContactDynamicsIntegrator::colourContacts()
{
	constexpr int     maxColours = 64;
	std::vector<uint64_t> taken(bodies.size(), 0);
	std::vector<int>      colour(contacts.size());
	std::vector<long>     count(maxColours + 1, 0);
	for (size_t k = 0; k < contacts.size(); ++k) {
		const int      b1 = contacts[k].b1, b2 = contacts[k].b2;
		const bool     d1 = records[b1].dynamic, d2 = records[b2].dynamic;
		const uint64_t used = (d1 ? taken[b1] : 0) | (d2 ? taken[b2] : 0);
		const int      col  = (~used == 0) ? maxColours : __builtin_ctzll(~used);
		if (col < maxColours) {
			if (d1) taken[b1] |= uint64_t(1) << col;
			if (d2) taken[b2] |= uint64_t(1) << col;
		}
		colour[k] = col;
		++count[col];
	}
	colourStart.assign(maxColours + 2, 0);
	for (int c = 0; c <= maxColours; ++c)
		colourStart[c + 1] = colourStart[c] + count[c];
	// store the contacts colour by colour (height order kept within a colour): each colour is
	// then one contiguous stretch of memory
	std::vector<long> next(colourStart.begin(), colourStart.end() - 1), order(contacts.size());
	for (size_t k = 0; k < contacts.size(); ++k)
		order[next[colour[k]]++] = long(k);
	// within a colour, by body ids: neighbouring contacts then touch neighbouring bodies in memory
	for (int c = 0; c <= maxColours; ++c)
		std::sort(order.begin() + colourStart[c], order.begin() + colourStart[c + 1], [this](long a, long b) {
			const SolverContact &ca = contacts[a], &cb = contacts[b];
			return ca.b1 < cb.b1 || (ca.b1 == cb.b1 && ca.b2 < cb.b2);
		});
	permuteContacts(order);
	nColours = 0;
	for (int c = 0; c <= maxColours; ++c)
		if (count[c]) nColours = c + 1;
	sweepChange.assign(contacts.size(), 0);
	statusChanged.assign(contacts.size(), 0);
}

// A sweep colour by colour, the contacts of a colour updated in parallel. Every contact's
// change is stored and summed afterwards in a fixed order: the result, bit for bit, does not
// depend on the number of threads.
Real ContactDynamicsIntegrator::colouredSweep(Real omega)
{
	constexpr long minParallelColour = 64; // below this a colour is swept by one thread (a parallel region costs a few µs)
	const int last = int(colourStart.size()) - 2; // the sequential overflow group
	for (int c = 0; c <= last; ++c) {
		const long begin = colourStart[c], end = colourStart[c + 1];
		const bool parallel = c < last && end - begin >= minParallelColour;
#pragma omp parallel for schedule(static) if (parallel)
		for (long idx = begin; idx < end; ++idx) {
			bool changed;
			sweepChange[idx]   = updateContact(idx, omega, changed);
			statusChanged[idx] = changed;
		}
	}
	Real change    = 0;
	nStatusChanges = 0;
	for (size_t k = 0; k < contacts.size(); ++k) {
		change += sweepChange[k];
		nStatusChanges += statusChanged[k];
	}
	return change;
}

// Slabs (sweepOrder 5): the contact points cut, across the wider horizontal extent, into
// `slabs` slabs of equal contact counts. A contact is inner when each of its dynamic bodies has
// all its contacts in the contact's slab; inner contacts of different slabs then share no body
// and their slabs can be swept at the same time. The rest (contacts of bodies that straddle a
// cut) form the interface, swept after the slabs. Height order is kept within every group.
void ContactDynamicsIntegrator::partitionSlabs()
{
	const long     nc = long(contacts.size());
	const int      ns = slabs;
	const Vector3r up = gravity.squaredNorm() > 0 ? Vector3r(-gravity.normalized()) : Vector3r::UnitZ();
	auto point = [this](long k) -> const Vector3r& { return static_cast<ScGeom*>(contacts[k].I->geom.get())->contactPoint; };
	int  axis  = 0;
	Real width = -1;
	for (int a = 0; a < 3; ++a) {
		if (math::abs(up[a]) > 0.5) continue; // along gravity: not a horizontal axis
		Real lo = std::numeric_limits<Real>::infinity(), hi = -lo;
		for (long k = 0; k < nc; ++k)
			lo = math::min(lo, point(k)[a]), hi = math::max(hi, point(k)[a]);
		if (hi - lo > width) width = hi - lo, axis = a;
	}
	std::vector<Real> x(nc);
	for (long k = 0; k < nc; ++k)
		x[k] = point(k)[axis];
	std::vector<Real> sorted(x);
	std::sort(sorted.begin(), sorted.end());
	std::vector<Real> cut(ns - 1);
	for (int s = 1; s < ns; ++s)
		cut[s - 1] = sorted[size_t(s) * nc / ns];
	std::vector<int>      group(nc);
	std::vector<uint64_t> touched(bodies.size(), 0);
	for (long k = 0; k < nc; ++k) {
		group[k]     = int(std::upper_bound(cut.begin(), cut.end(), x[k]) - cut.begin());
		const int b1 = contacts[k].b1, b2 = contacts[k].b2;
		if (records[b1].dynamic) touched[b1] |= uint64_t(1) << group[k];
		if (records[b2].dynamic) touched[b2] |= uint64_t(1) << group[k];
	}
	std::vector<long> count(ns + 1, 0);
	for (long k = 0; k < nc; ++k) {
		const uint64_t own = uint64_t(1) << group[k];
		const int      b1 = contacts[k].b1, b2 = contacts[k].b2;
		if ((records[b1].dynamic && touched[b1] != own) || (records[b2].dynamic && touched[b2] != own)) group[k] = ns;
		++count[group[k]];
	}
	blockStart.assign(ns + 2, 0);
	for (int g = 0; g <= ns; ++g)
		blockStart[g + 1] = blockStart[g] + count[g];
	std::vector<long> next(blockStart.begin(), blockStart.end() - 1), order(nc);
	for (long k = 0; k < nc; ++k)
		order[next[group[k]]++] = k;
	permuteContacts(order);
	nInterface = int(count[ns]);
	blockChange.assign(ns, 0);
	blockStatus.assign(ns, 0);
}

// A slab sweep: the slabs in parallel, each upwards, then the interface. Sums are taken slab
// by slab in a fixed order: the result, bit for bit, does not depend on the number of threads.
Real ContactDynamicsIntegrator::slabSweep(Real omega)
{
	const int ns = int(blockStart.size()) - 2;
#pragma omp parallel for schedule(static, 1) if (ns > 1 && blockStart[ns] >= 256)
	for (int s = 0; s < ns; ++s) {
		int n          = 0;
		blockChange[s] = sweepRange(blockStart[s], blockStart[s + 1], omega, n);
		blockStatus[s] = n;
	}
	Real change    = 0;
	nStatusChanges = 0;
	for (int s = 0; s < ns; ++s) {
		change += blockChange[s];
		nStatusChanges += blockStatus[s];
	}
	return change + sweepRange(blockStart[ns], blockStart[ns + 1], omega, nStatusChanges);
}


// Stage 6: nonlinear Gauss–Seidel over contacts. Each contact in turn: its local velocity
// without its own impulse, b = U − W r; the exact local solve of Ũ = A(W r + b + s); the
// impulse change applied to both bodies at once.
void ContactDynamicsIntegrator::solveImpulses()
{
	for (SolverContact& c : contacts)
		applyImpulse(c, c.r); // warm start
	residualHistory.clear();
	iterations = 0;
	residual   = 0;
	converged  = true;
	if (contacts.empty()) {
		nSticking = nSliding = nStatusChanges = 0;
		return;
	}
	converged   = false;
	const Real scale = qNorm > 0 ? qNorm : Real(1);
	Real omega = relaxation, bestChange = std::numeric_limits<Real>::infinity();
	int  stalled = 0;
	const bool coloured = sweepOrder == 4, slabbed = sweepOrder == 5;
	if (coloured) colourContacts();
	if (slabbed) partitionSlabs();
	if (momentum) startMomentum();
	// Momentum restarts when a sweep changes the velocities more than restartGrowth times the
	// sweep before. 1.2 rather than 1 lets momentum ride through small bumps (measured on pile
	// steps: 109 and 178 sweeps against 313 and 234 with 1); the stall guard below falls back to 1.
	Real tNesterov = 1, lastChange = std::numeric_limits<Real>::infinity(), restartGrowth = 1.2;
	for (int it = 1; it <= maxIter; ++it) {
		// Σ (W_NN |Δr|)²: the velocity changes this sweep made
		const bool down   = sweepOrder == 3 || (sweepOrder == 2 && it % 2 == 0);
		const Real change = coloured ? colouredSweep(omega) : slabbed ? slabSweep(omega) : orderedSweep(omega, !down);
		iterations = it;
		// The exact residual costs about a sweep: evaluate it only once the sweep's own changes
		// are below the tolerance (a converged state barely changes), or when asked to record.
		const bool quiet = math::sqrt(change) <= tolerance * scale;
		// Over-relaxation and a lenient momentum restart are not safe with friction: once the
		// sweeps stop contracting (the smallest change so far not improved by 1% for 50 sweeps),
		// finish the step with ω = 1 and momentum restarted at every growth.
		if (change < 0.99 * bestChange) {
			bestChange = change;
			stalled    = 0;
		} else if (++stalled >= 50 && (omega != 1 || restartGrowth != 1)) {
			omega         = 1;
			restartGrowth = 1;
			tNesterov     = 1;
		}
		if (it == maxIter || ((quiet || recordResidual) && it % checkEvery == 0)) {
			residual = computeResidual();
			if (recordResidual) residualHistory.push_back(residual);
			if (residual <= tolerance) {
				converged = true;
				break;
			}
		}
		if (momentum && it < maxIter) {
			// adaptive restart: a sweep that changed clearly more than the one before ends the momentum
			if (change > restartGrowth * lastChange) tNesterov = 1;
			lastChange      = change;
			const Real next = (1 + math::sqrt(1 + 4 * tNesterov * tNesterov)) / 2;
			extrapolateImpulses((tNesterov - 1) / next);
			tNesterov = next;
		}
	}
	syncHotContacts();
	if (!converged) {
		++nUnconverged;
		if (warnUnconverged)
			LOG_WARN(
			        "iter " << scene->iter << ": Gauss–Seidel stopped after maxIter=" << maxIter << " sweeps with residual " << residual
			                << " > tolerance=" << tolerance << " (" << contacts.size() << " contacts). Counted in nUnconverged.");
	}
}

// Nesterov momentum over whole sweeps. The velocities are affine in the impulses,
// V(r) = u_free + M⁻¹ H r, so the start of the next sweep, y = x_k + β (x_k − x_{k−1}), has
// velocities V(x_k) + β (V(x_k) − V(x_{k−1})): one pass over bodies. Where y leaves a contact's
// cone it is projected, and the projection's impulse is applied to the two bodies.
void ContactDynamicsIntegrator::startMomentum()
{
	rPrev.resize(contacts.size());
	for (size_t k = 0; k < contacts.size(); ++k)
		rPrev[k] = hot[k].fast ? hot[k].r : contacts[k].r;
	vPrev.resize(bodies.size());
	wPrev.resize(bodies.size());
	for (size_t b = 0; b < bodies.size(); ++b) {
		vPrev[b] = bodies[b].v;
		wPrev[b] = bodies[b].w;
	}
}

void ContactDynamicsIntegrator::extrapolateImpulses(Real beta)
{
	const long nb = long(bodies.size());
#pragma omp parallel for schedule(static) if (nb >= 4096)
	for (long b = 0; b < nb; ++b) { // obstacles: v = vPrev (never written), unchanged
		SolverBody&    B = bodies[b];
		const Vector3r v = B.v, w = B.w;
		B.v += beta * (v - vPrev[b]);
		B.w += beta * (w - wPrev[b]);
		vPrev[b] = v;
		wPrev[b] = w;
	}
	if (sweepOrder != 5) {
		extrapolateRange(0, long(contacts.size()), beta);
		return;
	}
	const int ns = int(blockStart.size()) - 2; // slabs: as in the sweep, slabs in parallel, then the interface
#pragma omp parallel for schedule(static, 1) if (ns > 1 && blockStart[ns] >= 256)
	for (int s = 0; s < ns; ++s)
		extrapolateRange(blockStart[s], blockStart[s + 1], beta);
	extrapolateRange(blockStart[ns], blockStart[ns + 1], beta);
}

// The contact part of the extrapolation for contacts [begin, end): y = x + β(x − x_prev); where
// y leaves the cone, its projection, whose impulse is applied to the two bodies.
void ContactDynamicsIntegrator::extrapolateRange(long begin, long end, Real beta)
{
	for (long k = begin; k < end; ++k) {
		const bool     fast = hot[k].fast;
		Vector3r&      r    = fast ? hot[k].r : contacts[k].r;
		const Vector3r x    = r;
		if (x == rPrev[k]) continue; // unchanged (open contacts mostly): y = x
		if (beta == 0) {             // a restart: y = x, already in its cone
			rPrev[k] = x;
			continue;
		}
		const Vector3r y  = x + beta * (x - rPrev[k]);
		const Real     mu = fast ? hot[k].mu : contacts[k].mu;
		rPrev[k]          = x;
		r                 = y;
		if (y[0] >= 0 && y[1] * y[1] + y[2] * y[2] <= mu * mu * y[0] * y[0]) continue; // inside the cone
		r = cd::projectOnCone(y, mu);
		if (fast) applySphereImpulse(hot[k], r - y);
		else
			applyImpulse(contacts[k], r - y);
	}
}

// Pseudo-velocities during the correction: translations in the compact pseudoV, rotations in
// the records (only general-path contacts make them).
Vector3r ContactDynamicsIntegrator::localPseudoVelocity(const SolverContact& c) const
{
	return c.frame * ((pseudoV[c.b2] + records[c.b2].pw.cross(c.c2)) - (pseudoV[c.b1] + records[c.b1].pw.cross(c.c1)));
}

void ContactDynamicsIntegrator::applyPseudoImpulse(const SolverContact& c, Real dP)
{
	const Vector3r P = c.frame.row(0).transpose() * dP;
	pseudoV[c.b2] += bodies[c.b2].invM.cwiseProduct(P);
	records[c.b2].pw += bodies[c.b2].invI * c.c2.cross(P);
	pseudoV[c.b1] -= bodies[c.b1].invM.cwiseProduct(P);
	records[c.b1].pw -= bodies[c.b1].invI * c.c1.cross(P);
}

// One correction sweep over rows [begin, end), forwards or backwards: returns the largest
// overlap beyond its allowance met (relative) before each row's update.
Real ContactDynamicsIntegrator::correctionRange(long begin, long end, bool forward)
{
	Real worst = 0;
	for (long j = begin; j < end; ++j) {
		const long     k   = forward ? j : end - 1 - (j - begin);
		CorrectionRow& row = corrections[k];
		// normal pseudo-velocity; for a sphere contact rotations never enter it (the lever arm
		// is along n) and a normal pseudo-impulse never makes them
		const Real un   = row.fast ? row.n.dot(pseudoV[row.b2] - pseudoV[row.b1]) : localPseudoVelocity(contacts[k])[0];
		const Real v    = row.overlap - row.lag * un; // > 0: overlap beyond the allowance
		worst           = math::max(worst, v);
		const Real Pnew = math::max(Real(0), row.P + row.gain * v);
		const Real dP   = Pnew - row.P;
		if (dP != 0) {
			if (row.fast) {
				pseudoV[row.b2] += row.m2 * dP * row.n;
				pseudoV[row.b1] -= row.m1 * dP * row.n;
			} else
				applyPseudoImpulse(contacts[k], dP);
		}
		row.P = Pnew;
	}
	return worst;
}

// Stage 7: position correction. The end-of-step gap is g_f = g_m + h/2 (U_f,N + Ũ_N), Ũ from
// normal pseudo-impulses P ≥ 0 that move positions but never velocities. Target: g_f ≥ −a,
// with a the contact's overlap allowance (CDPhys.overlapAllowance: the overlap it was created
// with, e.g. by packing generation, shrinking with the overlap). Such overlaps are kept, not
// pushed apart, so a packing at rest stays exactly at rest; the overlap that steps create (by
// the half-step predictor after a landing, or by an unconverged solve) is removed, over several
// steps if the correction itself stops at maxProjectionIter. Projected Gauss–Seidel, frictionless.
void ContactDynamicsIntegrator::correctPositions()
{
	const Real h          = scene->dt;
	projectionIterations  = 0;
	maxCorrectedOverlap   = 0;
	// the velocity part of the end-of-step gap is fixed now: g_m + h/2 U_f,N
	const long nc = long(contacts.size());
	corrections.resize(nc);
	for (long k = 0; k < nc; ++k) {
		const SolverContact& c   = contacts[k];
		CorrectionRow&       row = corrections[k];
		row.overlap              = (-c.allowance - c.gapM - 0.5 * h * localVelocity(c)[0]) / c.refR;
		maxCorrectedOverlap      = math::max(maxCorrectedOverlap, row.overlap);
	}
	if (maxCorrectedOverlap <= positionTolerance) return;
	for (long k = 0; k < nc; ++k) {
		const SolverContact& c   = contacts[k];
		const SphereContact& f   = hot[k];
		CorrectionRow&       row = corrections[k];
		row.lag                  = 0.5 * h / c.refR;
		row.gain                 = (2 / h) * c.refR / c.W(0, 0);
		row.P                    = 0;
		row.fast                 = f.fast;
		row.b1 = c.b1, row.b2 = c.b2;
		if (f.fast) row.n = f.n, row.m1 = f.m1, row.m2 = f.m2;
	}
	pseudoV.assign(bodies.size(), Vector3r::Zero());
	const bool slabbed = sweepOrder == 5 && blockStart.size() >= 2 && blockStart.back() == nc;
	for (int it = 1; it <= maxProjectionIter; ++it) {
		const bool forward = it % 2 == 1; // alternating directions
		Real       worst   = 0;
		if (!slabbed) worst = correctionRange(0, nc, forward);
		else { // as the slab sweep: slabs in parallel, the interface after them (before them backwards)
			const int ns = int(blockStart.size()) - 2;
			if (!forward) worst = correctionRange(blockStart[ns], blockStart[ns + 1], false);
#pragma omp parallel for schedule(static, 1) reduction(max : worst) if (ns > 1 && blockStart[ns] >= 256)
			for (int s = 0; s < ns; ++s)
				worst = math::max(worst, correctionRange(blockStart[s], blockStart[s + 1], forward));
			if (forward) worst = math::max(worst, correctionRange(blockStart[ns], blockStart[ns + 1], true));
		}
		projectionIterations = it;
		if (worst <= positionTolerance) break;
	}
	for (size_t b = 0; b < bodies.size(); ++b)
		records[b].pv = pseudoV[b];
}

// Stage 8: q_f = q_m + h/2 (u_f + ũ), with u_f written to the bodies. Kinematic bodies and
// blocked DOFs keep their imposed velocity. NaNs are caught here, before anything is stored.
void ContactDynamicsIntegrator::updatePositions()
{
	const Real h = scene->dt;
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const SolverBody& sb = bodies[b->id];
		const BodyRecord& br = records[b->id];
		if (!finite(sb.v) || !finite(sb.w) || !finite(br.pv) || !finite(br.pw))
			throw std::runtime_error("iter " + std::to_string(scene->iter) + ": body #" + std::to_string(b->id) + " got a NaN velocity in the Contact Dynamics step.");
	}
	for (const auto& b : *scene->bodies) {
		if (!b) continue;
		const SolverBody& sb = bodies[b->id];
		const BodyRecord& br = records[b->id];
		State&            s  = *b->state;
		if (br.dynamic) {
			s.vel    = sb.v;
			s.angVel = sb.w;
		}
		s.pos += 0.5 * h * (s.vel + br.pv);
		rotate(s.ori, s.angVel + br.pw, 0.5 * h);
	}
}

void ContactDynamicsIntegrator::restoreStartOfStep()
{
	for (const auto& b : *scene->bodies) {
		if (!b || !records[b->id].active) continue;
		const BodyRecord& br = records[b->id];
		b->state->pos    = br.qi;
		b->state->ori    = br.oi;
		b->state->vel    = br.vi;
		b->state->angVel = br.wi;
	}
}

// Stage 9: impulses (warm start) and forces into CDPhys, contact forces into O.forces, energy,
// and the collider's hint (NewtonIntegrator::maxVelocitySq, as NewtonIntegrator sets it).
void ContactDynamicsIntegrator::storeResults()
{
	const Real h = scene->dt;
	for (const SolverContact& c : contacts) {
		auto*          phys = static_cast<CDPhys*>(c.I->phys.get());
		phys->impulse       = c.frame.transpose() * c.r;
		phys->status        = c.status;
		phys->overlapAllowance = c.allowance;
		phys->normalForce   = c.frame.row(0).transpose() * (c.r[0] / h);
		phys->shearForce    = (c.frame.row(1).transpose() * c.r[1] + c.frame.row(2).transpose() * c.r[2]) / h;
		// a contact that landed keeps its approach velocity for the next step's restitution law
		const bool landed      = c.gapM > 0 && c.r[0] > 0 && (phys->en > 0 || phys->et != 0);
		phys->approachVelocity = landed ? Vector3r(c.frame.transpose() * c.Ui) : Vector3r::Zero();
	}
	if (scene->trackEnergy) trackEnergy(); // O.forces still holds only the external forces here
	for (const SolverContact& c : contacts) {
		const Vector3r P = c.frame.transpose() * c.r;
		scene->forces.addForce(c.b2, P / h);
		scene->forces.addTorque(c.b2, c.c2.cross(P) / h);
		scene->forces.addForce(c.b1, -P / h);
		scene->forces.addTorque(c.b1, -c.c1.cross(P) / h);
	}
	scene->forces.sync();

	// collider hint: > 1 when some body left its bound's sweep distance
	maxVelocitySq = 0;
#ifdef YADE_OPENMP
	std::fill(threadMaxVelocitySq.begin(), threadMaxVelocitySq.end(), Real(0));
#endif
	for (const auto& b : *scene->bodies)
		if (b) saveMaximaDisplacement(b);
#ifdef YADE_OPENMP
	for (const Real& m : threadMaxVelocitySq)
		maxVelocitySq = math::max(maxVelocitySq, m);
#endif
}

} // namespace yade

namespace yade {

// Energy balance of the step, exact for the midpoint scheme: with ū = (u_i + u_f)/2,
// ΔKE = ū·(h F_ext + h m g) + Σ_α r_α·Ū_α − Σ_kinematic ū_b·P_b, and q_f − q_i = h ū (+ the
// pseudo-displacement of the position correction, booked as "positionCorrection").
// Names follow YADE's: every term is minus a work, so O.energy.total() stays constant.
void ContactDynamicsIntegrator::trackEnergy()
{
	const Real h             = scene->dt;
	Real       contactDissip = 0, kinematicWork = 0;
	for (const SolverContact& c : contacts) {
		contactDissip -= c.r.dot(0.5 * (c.Ui + localVelocity(c)));
		const Vector3r P = c.frame.transpose() * c.r;
		for (int side = 0; side < 2; ++side) {
			const int         id = side ? c.b2 : c.b1;
			const BodyRecord& br = records[id];
			if (br.dynamic) continue;
			const SolverBody& sb = bodies[id];
			const Vector3r    Pb = side ? P : Vector3r(-P);
			const Vector3r    cb = side ? c.c2 : c.c1;
			kinematicWork += Pb.dot(0.5 * (br.vi + sb.v)) + cb.cross(Pb).dot(0.5 * (br.wi + sb.w));
		}
	}
	Real kinetic = 0, gravWork = 0, extWork = 0, posCorr = 0;
	for (const auto& b : *scene->bodies) {
		if (!b || !records[b->id].dynamic) continue;
		const SolverBody& sb = bodies[b->id];
		const BodyRecord& br = records[b->id];
		const State&      s  = *b->state;
		const Matrix3r    R  = s.ori.toRotationMatrix();
		kinetic += 0.5 * s.mass * s.vel.squaredNorm() + 0.5 * s.angVel.dot(R * s.inertia.asDiagonal() * R.transpose() * s.angVel);
		Vector3r g = gravity;
		for (int k = 0; k < 3; ++k)
			if (sb.invM[k] == 0) g[k] = 0;
		gravWork -= s.mass * g.dot(s.pos - br.qi);
		posCorr += s.mass * g.dot(0.5 * h * br.pv);
		extWork -= h * (scene->forces.getForce(b->id).dot(0.5 * (br.vi + sb.v)) + scene->forces.getTorque(b->id).dot(0.5 * (br.wi + sb.w)));
	}
	scene->energy->add(kinetic, "kinetic", kinEnergyIx, /*reset*/ true);
	scene->energy->add(gravWork, "gravWork", fieldWorkIx, false);
	scene->energy->add(contactDissip, "contactDissip", contactDissipIx, false);
	if (extWork != 0) scene->energy->add(extWork, "externalWork", extWorkIx, false);
	if (kinematicWork != 0) scene->energy->add(kinematicWork, "kinematicWork", kinematicWorkIx, false);
	if (posCorr != 0) scene->energy->add(posCorr, "positionCorrection", posCorrIx, false);
}

} // namespace yade
