// Contact Dynamics plugin for YADE: contact physics, its Ip2 functor and the Law2 functor.
//
// CD contacts carry no stiffness. A CDPhys stores the friction coefficient, the restitution
// coefficients and the contact impulse of the last step (the warm start of the next one).
// Forces are written back in YADE's places: normalForce and shearForce are the force exerted
// on body 2 by body 1 over the last step (impulse / dt), as for every FrictPhys.
#pragma once

#include <core/Dispatching.hpp>
#include <pkg/common/ElastMat.hpp>
#include <pkg/dem/FrictPhys.hpp>
#include <pkg/dem/ScGeom.hpp>

namespace yade {

class CDPhys : public FrictPhys {
public:
	virtual ~CDPhys() = default;
	// clang-format off
	YADE_CLASS_BASE_DOC_ATTRS_CTOR(CDPhys, FrictPhys,
		"Contact physics of a rigid Contact Dynamics contact (:yref:`ContactDynamicsIntegrator`). It derives from :yref:`FrictPhys` so that YADE's utilities (``utils.getStress``, ``utils.unbalancedForce``...) read its forces; :yref:`kn<NormPhys.kn>` and :yref:`ks<NormShearPhys.ks>` stay 0, since contacts are rigid. :yref:`normalForce<NormPhys.normalForce>` and :yref:`shearForce<NormShearPhys.shearForce>` are the mean force exerted on body 2 by body 1 over the last step (impulse / dt) [N].",
		((Real, en, 0, , "Normal restitution coefficient [-], in [0,1]. Moreau's law is applied to the weighted mean (U_f + en·U_i)/(1+en) of the initial and final normal relative velocities."))
		((Real, et, 0, , "Tangential restitution coefficient [-], in [-1,1] (0: no tangential restitution); applied as en is, to the tangential velocity."))
		((Vector3r, impulse, Vector3r::Zero(), , "Contact impulse on body 2 over the last step, in global coordinates [N·s]. It warm-starts the next step's solve. Written by the solver; set from Python only to restore a saved state (``yadecd.runs.runstate``). |yupdate|"))
		((int, status, 0, , "Contact status after the last solve: 0 open (no impulse), 1 sticking, 2 sliding. Written by the solver; set from Python only to restore a saved state. |yupdate|"))
		((Real, overlapAllowance, NaN, , "Overlap this contact may keep [m]: the overlap it was created with (e.g. by packing generation), shrinking whenever the overlap does; NaN until its first step. The position correction of :yref:`ContactDynamicsIntegrator` removes any overlap beyond it. Set from Python only to restore a saved state. |yupdate|"))
		((Vector3r, approachVelocity, Vector3r::Zero(), , "For a contact that closed within the last step (landing), the relative velocity (global coordinates) it had at the start of that step [m/s]; used as the initial velocity of the restitution law at the next step. Zero otherwise. Set from Python only to restore a saved state. |yupdate|"))
		,
		createIndex();
	);
	// clang-format on
	REGISTER_CLASS_INDEX(CDPhys, FrictPhys);
};
REGISTER_SERIALIZABLE(CDPhys);

class Ip2_FrictMat_FrictMat_CDPhys : public IPhysFunctor {
public:
	void go(const shared_ptr<Material>& m1, const shared_ptr<Material>& m2, const shared_ptr<Interaction>& I) override;
	void postLoad(Ip2_FrictMat_FrictMat_CDPhys&);
	FUNCTOR2D(FrictMat, FrictMat);
	// clang-format off
	YADE_CLASS_BASE_DOC_ATTRS(Ip2_FrictMat_FrictMat_CDPhys, IPhysFunctor,
		"Create a :yref:`CDPhys` from two :yref:`FrictMat`: friction coefficient μ = tan(min(φ1, φ2)) from the materials' :yref:`frictionAngle<FrictMat.frictionAngle>` (each in [0, π/2): a contact between materials outside it fails the next step, naming the pair); restitution from :yref:`en<Ip2_FrictMat_FrictMat_CDPhys.en>` and :yref:`et<Ip2_FrictMat_FrictMat_CDPhys.et>`. Stiffness and Young's modulus are ignored: contacts are rigid.",
		((Real, en, 0, Attr::triggerPostLoad, "Normal restitution coefficient given to new contacts [-], in [0,1]."))
		((Real, et, 0, Attr::triggerPostLoad, "Tangential restitution coefficient given to new contacts [-], in [-1,1]."))
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Ip2_FrictMat_FrictMat_CDPhys);

class Law2_ScGeom_CDPhys_Coulomb : public LawFunctor {
public:
	bool go(shared_ptr<IGeom>&, shared_ptr<IPhys>&, Interaction*) override;
	FUNCTOR2D(ScGeom, CDPhys);
	// clang-format off
	YADE_CLASS_BASE_DOC(Law2_ScGeom_CDPhys_Coulomb, LawFunctor,
		"Contact law of Contact Dynamics: it applies no force itself. It keeps each contact within the alert distance alive for :yref:`ContactDynamicsIntegrator`, which solves all contact impulses together (Signorini–Coulomb law, nonlinear Gauss–Seidel) and writes the forces back into the :yref:`CDPhys`. Contacts whose gap exceeds twice the alert distance (see :yref:`ContactDynamicsIntegrator.alertRatio`) are erased; the factor 2 keeps contacts from flickering, which would lose their warm start."
	);
	// clang-format on
};
REGISTER_SERIALIZABLE(Law2_ScGeom_CDPhys_Coulomb);

} // namespace yade
