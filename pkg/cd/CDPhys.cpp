#include "CDPhys.hpp"
#include "ContactDynamicsIntegrator.hpp"
#include <core/Scene.hpp>

namespace yade {

YADE_PLUGIN((CDPhys)(Ip2_FrictMat_FrictMat_CDPhys)(Law2_ScGeom_CDPhys_Coulomb));

void Ip2_FrictMat_FrictMat_CDPhys::postLoad(Ip2_FrictMat_FrictMat_CDPhys&)
{
	if (!(en >= 0 && en <= 1)) throw std::invalid_argument("Ip2_FrictMat_FrictMat_CDPhys.en=" + std::to_string(en) + ": the normal restitution coefficient must lie in [0,1].");
	if (!(et >= -1 && et <= 1))
		throw std::invalid_argument("Ip2_FrictMat_FrictMat_CDPhys.et=" + std::to_string(et) + ": the tangential restitution coefficient must lie in [-1,1].");
}

void Ip2_FrictMat_FrictMat_CDPhys::go(const shared_ptr<Material>& m1, const shared_ptr<Material>& m2, const shared_ptr<Interaction>& I)
{
	if (I->phys) return; // keep the existing contact and its warm-start impulse
	auto       phys = shared_ptr<CDPhys>(new CDPhys);
	const Real phi1 = static_cast<FrictMat*>(m1.get())->frictionAngle, phi2 = static_cast<FrictMat*>(m2.get())->frictionAngle;
	const auto valid = [](Real phi) { return phi >= 0 && phi < Mathr::HALF_PI; };
	// A bad friction angle (either material's) is reported by the integrator (outside OpenMP regions), see
	// gatherContacts: NaN here, since tan() of an angle past π/2 can be a plausible coefficient (tan(π + 0.1) = 0.1).
	phys->tangensOfFrictionAngle = (valid(phi1) && valid(phi2)) ? math::tan(math::min(phi1, phi2)) : Real(NaN);
	phys->en                     = en;
	phys->et                     = et;
	I->phys                      = phys;
}

bool Law2_ScGeom_CDPhys_Coulomb::go(shared_ptr<IGeom>& ig, shared_ptr<IPhys>&, Interaction* I)
{
	const ScGeom* g   = static_cast<ScGeom*>(ig.get());
	const State&  s1  = *Body::byId(I->getId1(), scene)->state;
	const State&  s2  = *Body::byId(I->getId2(), scene)->state;
	const Real    gap = -g->penetrationDepth;
	if (gap <= 0) return true;
	const Real alert = ContactDynamicsIntegrator::alertDistance(scene, math::min(g->refR1, g->refR2), s1.vel.norm() + s2.vel.norm());
	return gap <= 2 * alert;
}

} // namespace yade
