// Contact Dynamics plugin for YADE: near-contact detection.
//
// A CD step must see every contact that can close within the step, with its gap, or a fast
// grain tunnels through a wall or another grain. A pair becomes a contact (a real interaction
// with a ScGeom) when its gap is below the alert distance
//
//     d_alert = alertRatio · min(r1, r2) + alertSpeedFactor · dt · (|v1| + |v2|)
//
// (:yref:`ContactDynamicsIntegrator.alertRatio`, :yref:`ContactDynamicsIntegrator.alertSpeedFactor`).
// YADE's own functors cannot do this: the sphere–sphere one has only a relative detection
// factor, and the wall, facet and box ones create nothing before overlap. These subclasses add
// only the creation test; once a contact exists they run YADE's own geometry, but for the signed
// gap of a sphere centre that the half-step predictor has put behind a wall or inside a box.
#pragma once

#include <pkg/common/Bo1_Aabb.hpp>
#include <pkg/dem/Ig2_Box_Sphere_ScGeom.hpp>
#include <pkg/dem/Ig2_Facet_Sphere_ScGeom.hpp>
#include <pkg/dem/Ig2_Sphere_Sphere_ScGeom.hpp>

namespace yade {

class Bo1_Sphere_CDAabb : public Bo1_Sphere_Aabb {
public:
	void go(const shared_ptr<Shape>& cm, shared_ptr<Bound>& bv, const Se3r&, const Body*) override;
	FUNCTOR1D(Sphere);
	// clang-format off
	YADE_CLASS_BASE_DOC(Bo1_Sphere_CDAabb, Bo1_Sphere_Aabb,
		"Bounding box of a sphere for Contact Dynamics: the sphere's box grown by its own alert distance, alertRatio·r + alertSpeedFactor·dt·|v| (see :yref:`ContactDynamicsIntegrator.alertRatio`), so that the collider proposes every pair that can come into contact within a step. :yref:`aabbEnlargeFactor<Bo1_Sphere_Aabb.aabbEnlargeFactor>` is ignored."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Bo1_Sphere_CDAabb);

class Ig2_Sphere_Sphere_CDScGeom : public Ig2_Sphere_Sphere_ScGeom {
public:
	bool go(const shared_ptr<Shape>&, const shared_ptr<Shape>&, const State&, const State&, const Vector3r&, const bool&, const shared_ptr<Interaction>&) override;
	bool goReverse(const shared_ptr<Shape>&, const shared_ptr<Shape>&, const State&, const State&, const Vector3r&, const bool&, const shared_ptr<Interaction>&) override;
	FUNCTOR2D(Sphere, Sphere);
	DEFINE_FUNCTOR_ORDER_2D(Sphere, Sphere);
	// clang-format off
	YADE_CLASS_BASE_DOC(Ig2_Sphere_Sphere_CDScGeom, Ig2_Sphere_Sphere_ScGeom,
		"Sphere–sphere :yref:`ScGeom` for Contact Dynamics: a contact is created when the gap is below the alert distance (see :yref:`ContactDynamicsIntegrator.alertRatio`); the geometry is then YADE's :yref:`Ig2_Sphere_Sphere_ScGeom`. :yref:`interactionDetectionFactor<Ig2_Sphere_Sphere_ScGeom.interactionDetectionFactor>` is ignored."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Ig2_Sphere_Sphere_CDScGeom);

class Ig2_Wall_Sphere_CDScGeom : public Ig2_Wall_Sphere_ScGeom {
public:
	bool go(const shared_ptr<Shape>&, const shared_ptr<Shape>&, const State&, const State&, const Vector3r&, const bool&, const shared_ptr<Interaction>&) override;
	FUNCTOR2D(Wall, Sphere);
	DEFINE_FUNCTOR_ORDER_2D(Wall, Sphere);
	// clang-format off
	YADE_CLASS_BASE_DOC(Ig2_Wall_Sphere_CDScGeom, Ig2_Wall_Sphere_ScGeom,
		"Wall–sphere :yref:`ScGeom` for Contact Dynamics: a contact is created when the sphere's gap to the wall plane is below the alert distance (see :yref:`ContactDynamicsIntegrator.alertRatio`); the geometry is then YADE's :yref:`Ig2_Wall_Sphere_ScGeom` (body 1 is the wall)."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Ig2_Wall_Sphere_CDScGeom);

class Ig2_Facet_Sphere_CDScGeom : public Ig2_Facet_Sphere_ScGeom {
public:
	bool go(const shared_ptr<Shape>&, const shared_ptr<Shape>&, const State&, const State&, const Vector3r&, const bool&, const shared_ptr<Interaction>&) override;
	FUNCTOR2D(Facet, Sphere);
	DEFINE_FUNCTOR_ORDER_2D(Facet, Sphere);
	// clang-format off
	YADE_CLASS_BASE_DOC(Ig2_Facet_Sphere_CDScGeom, Ig2_Facet_Sphere_ScGeom,
		"Facet–sphere :yref:`ScGeom` for Contact Dynamics: a contact is created when the sphere's gap to the facet is below the alert distance (see :yref:`ContactDynamicsIntegrator.alertRatio`); the geometry is then YADE's :yref:`Ig2_Facet_Sphere_ScGeom` (body 1 is the facet)."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Ig2_Facet_Sphere_CDScGeom);

class Ig2_Box_Sphere_CDScGeom : public Ig2_Box_Sphere_ScGeom {
public:
	bool go(const shared_ptr<Shape>&, const shared_ptr<Shape>&, const State&, const State&, const Vector3r&, const bool&, const shared_ptr<Interaction>&) override;
	FUNCTOR2D(Box, Sphere);
	DEFINE_FUNCTOR_ORDER_2D(Box, Sphere);
	// clang-format off
	YADE_CLASS_BASE_DOC(Ig2_Box_Sphere_CDScGeom, Ig2_Box_Sphere_ScGeom,
		"Box–sphere :yref:`ScGeom` for Contact Dynamics (body 1 is the box, body 2 the sphere, the normal points from the box to the sphere).\n\n"
		"*Creation*: a contact is created when the sphere's gap to the box, g = d − r with d the signed distance from the sphere's centre to the box (to the closest point of its surface when outside, minus the depth below the nearest face when inside), is below the alert distance (see :yref:`ContactDynamicsIntegrator.alertRatio`; the box's speed counted there is that of its centre: its spin is not). :yref:`interactionDetectionFactor<Ig2_Box_Sphere_ScGeom.interactionDetectionFactor>` is ignored.\n\n"
		"*Geometry* (YADE's :yref:`Ig2_Box_Sphere_ScGeom`, exact): with the centre outside the box, the closest point p of the box to the centre c; the normal is (c − p)/|c − p|, i.e. the face normal over a face, perpendicular to the edge near an edge, along c − corner near a corner; the penetration depth is r − |c − p|, the contact point the middle of p and c − r·n.\n\n"
		"*Centre inside the box* (the half-step predictor of :yref:`ContactDynamicsIntegrator` can put it there in an impact): YADE takes the face nearest the centre, which for a centre past the mid-plane of a thin box is the opposite face, a mirrored contact that would push the sphere through. For an existing contact this functor keeps instead the face the previous normal points out of (its largest component in the box's axes), i.e. the face the sphere came through, with the signed depth: normal = that face's outward normal, penetration depth = r + depth of the centre below that face. A contact created with the centre already inside (a sphere generated inside a box) gets YADE's nearest face. (At the mid-step the integrator, seeing an overlap deeper than r, keeps the start-of-step frame and predicts the gap linearly anyway.)\n\n"
		":yref:`hertzian<Ig2_Box_Sphere_ScGeom.hertzian>` is honoured (it changes only refR1, which Contact Dynamics does not use: it takes the smaller radius)."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Ig2_Box_Sphere_CDScGeom);

} // namespace yade
