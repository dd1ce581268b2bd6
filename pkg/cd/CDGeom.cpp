#include "CDGeom.hpp"
#include "ContactDynamicsIntegrator.hpp"
#include <core/Scene.hpp>
#include <core/Aabb.hpp>
#include <pkg/dem/ScGeom.hpp>
#include <pkg/common/Box.hpp>
#include <pkg/common/Facet.hpp>
#include <pkg/common/Wall.hpp>

namespace yade {

YADE_PLUGIN((Bo1_Sphere_CDAabb)(Ig2_Sphere_Sphere_CDScGeom)(Ig2_Wall_Sphere_CDScGeom)(Ig2_Facet_Sphere_CDScGeom)(Ig2_Box_Sphere_CDScGeom));

namespace {
	// Two bodies that cannot move (fixed paving grains, walls) never exchange an impulse: no contact.
	bool bothObstacles(const State& s1, const State& s2) { return s1.blockedDOFs == State::DOF_ALL && s2.blockedDOFs == State::DOF_ALL; }
}

void Bo1_Sphere_CDAabb::go(const shared_ptr<Shape>& cm, shared_ptr<Bound>& bv, const Se3r& se3, const Body* b)
{
	// (never throw here: this runs inside an OpenMP loop)
	const Real r = static_cast<Sphere*>(cm.get())->radius;
	if (!bv) bv = shared_ptr<Bound>(new Aabb);
	// each box grows by the sphere's whole alert distance (own radius and speed), so that an
	// obstacle whose box does not grow (a fixed wall or facet) is covered too
	const Real grow = ContactDynamicsIntegrator::alertDistance(scene, r, b ? b->state->vel.norm() : Real(0));
	Vector3r   half = Vector3r::Constant(r + grow);
	if (!scene->isPeriodic) {
		bv->min = se3.position - half;
		bv->max = se3.position + half;
		return;
	}
	// periodic cell: YADE's box in the cell's unsheared frame (as Bo1_Sphere_Aabb), grown so that
	// the sphere does not stick out of it when the cell is sheared
	if (scene->cell->hasShear()) {
		const Vector3r  ref = half;
		const Vector3r& cos = scene->cell->getCos();
		for (int i = 0; i < 3; i++) {
			const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
			half[i1] += .5 * ref[i1] * (1 / cos[i] - 1);
			half[i2] += .5 * ref[i2] * (1 / cos[i] - 1);
		}
	}
	bv->min = scene->cell->unshearPt(se3.position) - half;
	bv->max = scene->cell->unshearPt(se3.position) + half;
}

bool Ig2_Sphere_Sphere_CDScGeom::go(
        const shared_ptr<Shape>&       cm1,
        const shared_ptr<Shape>&       cm2,
        const State&                   s1,
        const State&                   s2,
        const Vector3r&                shift2,
        const bool&                    force,
        const shared_ptr<Interaction>& c)
{
	if (!c->isReal() && !force) {
		if (bothObstacles(s1, s2)) return false;
		const Real r1 = static_cast<Sphere*>(cm1.get())->radius, r2 = static_cast<Sphere*>(cm2.get())->radius;
		const Real gap   = (s2.pos + shift2 - s1.pos).norm() - r1 - r2;
		const Real alert = ContactDynamicsIntegrator::alertDistance(scene, math::min(r1, r2), s1.vel.norm() + s2.vel.norm());
		if (gap > alert) return false;
	}
	return Ig2_Sphere_Sphere_ScGeom::go(cm1, cm2, s1, s2, shift2, /*force*/ true, c);
}

bool Ig2_Sphere_Sphere_CDScGeom::goReverse(
        const shared_ptr<Shape>&       cm1,
        const shared_ptr<Shape>&       cm2,
        const State&                   s1,
        const State&                   s2,
        const Vector3r&                shift2,
        const bool&                    force,
        const shared_ptr<Interaction>& c)
{
	return go(cm1, cm2, s2, s1, -shift2, force, c);
}

bool Ig2_Wall_Sphere_CDScGeom::go(
        const shared_ptr<Shape>&       cm1,
        const shared_ptr<Shape>&       cm2,
        const State&                   s1,
        const State&                   s2,
        const Vector3r&                shift2,
        const bool&                    force,
        const shared_ptr<Interaction>& c)
{
	if (!c->isReal() && !force) {
		if (bothObstacles(s1, s2)) return false;
		const int  ax    = static_cast<Wall*>(cm1.get())->axis;
		const Real r     = static_cast<Sphere*>(cm2.get())->radius;
		const Real gap   = math::abs(s2.pos[ax] + shift2[ax] - s1.pos[ax]) - r;
		const Real alert = ContactDynamicsIntegrator::alertDistance(scene, r, s1.vel.norm() + s2.vel.norm());
		if (gap > alert) return false;
	}
	Ig2_Wall_Sphere_ScGeom::go(cm1, cm2, s1, s2, shift2, /*force*/ true, c);
	// YADE measures the gap with |distance|, which mirrors a sphere whose centre has crossed a
	// one-sided wall (sense = ±1); CD's half-step predictor can put it there. Use the signed one.
	const Wall* w = static_cast<Wall*>(cm1.get());
	if (w->sense != 0) {
		const Real r    = static_cast<Sphere*>(cm2.get())->radius;
		const Real dist = (s2.pos[w->axis] + shift2[w->axis] - s1.pos[w->axis]) * w->sense;
		ScGeom*    g    = static_cast<ScGeom*>(c->geom.get());
		g->penetrationDepth = r - dist;
	}
	return true;
}

bool Ig2_Facet_Sphere_CDScGeom::go(
        const shared_ptr<Shape>&       cm1,
        const shared_ptr<Shape>&       cm2,
        const State&                   s1,
        const State&                   s2,
        const Vector3r&                shift2,
        const bool&                    force,
        const shared_ptr<Interaction>& c)
{
	if (c->isReal() || force) return Ig2_Facet_Sphere_ScGeom::go(cm1, cm2, s1, s2, shift2, force, c);
	if (bothObstacles(s1, s2)) return false;
	// YADE's facet functor creates geometry only on overlap. Ask it about a sphere inflated by
	// the alert distance; if that one overlaps, the true gap is within the alert distance, and
	// the geometry is rebuilt for the true radius (YADE's functor accepts any gap once the
	// geometry exists).
	const Real r     = static_cast<Sphere*>(cm2.get())->radius;
	const Real alert = ContactDynamicsIntegrator::alertDistance(scene, r, s1.vel.norm() + s2.vel.norm());
	thread_local shared_ptr<Shape> inflated(new Sphere);
	static_cast<Sphere*>(inflated.get())->radius = r + alert;
	if (!Ig2_Facet_Sphere_ScGeom::go(cm1, inflated, s1, s2, shift2, false, c)) return false;
	ScGeom*    g   = static_cast<ScGeom*>(c->geom.get());
	const Real pen = g->penetrationDepth - alert;
	g->penetrationDepth = pen;
	g->contactPoint     = s2.pos + shift2 - (r - 0.5 * pen) * g->normal;
	g->radius1          = hertzian ? g->radius1 * r / (r + alert) : 2 * r;
	g->radius2          = r;
	return true;
}

bool Ig2_Box_Sphere_CDScGeom::go(
        const shared_ptr<Shape>&       cm1,
        const shared_ptr<Shape>&       cm2,
        const State&                   s1,
        const State&                   s2,
        const Vector3r&                shift2,
        const bool&                    force,
        const shared_ptr<Interaction>& c)
{
	const Vector3r& extents = static_cast<Box*>(cm1.get())->extents;
	const Real      r       = static_cast<Sphere*>(cm2.get())->radius;
	// the sphere's centre in the box's axes, computed as YADE's functor does (same inside test)
	const Matrix3r boxAxisT = s1.ori.toRotationMatrix();
	const Matrix3r boxAxis  = boxAxisT.transpose();
	const Vector3r centre   = s2.pos + shift2;
	const Vector3r local    = boxAxis * (centre - s1.pos);
	const Vector3r beyond   = local.cwiseAbs() - extents; // > 0: outside that pair of faces
	const bool     inside   = beyond.maxCoeff() <= 0;
	if (!c->isReal() && !force) {
		if (bothObstacles(s1, s2)) return false;
		// signed distance from the centre to the box: to its closest point outside, minus the
		// depth below the nearest face inside
		const Real dist  = inside ? beyond.maxCoeff() : beyond.cwiseMax(Real(0)).norm();
		const Real alert = ContactDynamicsIntegrator::alertDistance(scene, r, s1.vel.norm() + s2.vel.norm());
		if (dist - r > alert) return false;
	}
	if (!inside || !c->geom) return Ig2_Box_Sphere_ScGeom::go(cm1, cm2, s1, s2, shift2, /*force*/ true, c);
	// Centre inside, existing contact: YADE would take the nearest face, the opposite one for a
	// centre past the mid-plane of a thin box (a mirrored contact). Keep the face the previous
	// normal points out of (the one the sphere came through), with the signed depth below it.
	ScGeom*        g         = static_cast<ScGeom*>(c->geom.get());
	const Vector3r prevLocal = boxAxis * g->normal;
	int            k         = 0;
	prevLocal.cwiseAbs().maxCoeff(&k);
	const Real side    = prevLocal[k] >= 0 ? 1 : -1;
	Vector3r   nLocal  = Vector3r::Zero();
	nLocal[k]          = side;
	const Vector3r n   = boxAxisT * nLocal;
	const Real depth   = extents[k] - side * local[k]; // ≥ 0: the centre's depth below that face
	const Vector3r pt1 = centre + depth * n;          // on the face
	const Vector3r pt2 = centre - r * n;              // deepest point of the sphere
	constexpr Real hertzFac = 1e8;                     // Ig2_Box_Sphere_ScGeom's (private there)
	g->doIg2Work(0.5 * (pt1 + pt2), r + depth, hertzian ? hertzFac * r : r, r, s1, s2, scene, c, n, shift2, /*newScGeom*/ false, /*avoidGranularRatcheting*/ true);
	return true;
}

} // namespace yade
