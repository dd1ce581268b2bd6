// Contact Dynamics solver core: the single-contact (local) Signorini–Coulomb problem.
//
// pkg/cd/core/ holds the parts of the solver that need nothing from YADE but its Real and Eigen
// types (lib/base/Math.hpp): they never touch YADE objects, and are tested without running YADE
// by tests/core/ (the cd_core_tests target of the top-level CMake).
//
// Notation (Moreau; Jean; Siconos `fc3d`): every vector is written in the contact's local frame
// (n, t1, t2), normal component first. `r` is the contact impulse exerted on body 2 [N·s],
// compression positive (r_N ≥ 0). `U` is the relative velocity of body 2 with respect to body 1
// at the contact point [m/s]; U_N > 0 means the bodies separate.
//
// The local problem: given a 3×3 Delassus block W (symmetric positive definite) and a velocity
// offset b, find r such that U = W r + b obeys the Signorini–Coulomb law
//
//     U_N ≥ 0,  r_N ≥ 0,  U_N r_N = 0                             (unilateral)
//     |r_T| ≤ μ r_N;  |r_T| < μ r_N ⇒ U_T = 0;  else r_T = −μ r_N U_T/|U_T|   (Coulomb)
//
// Its three solution branches are the contact status: Open (r = 0), Sticking (U = 0, r inside
// the cone) and Sliding (r on the cone boundary). The law is the exact cone: no faceting,
// no decoupling of normal and tangential parts.
#pragma once

#include <lib/base/Math.hpp>

#include <cmath>
#include <limits>

namespace yade {
namespace cd {

	enum class ContactStatus : int { Open = 0, Sticking = 1, Sliding = 2 };

	/*! Euclidean projection of z onto the Coulomb cone C_μ = {r : |r_T| ≤ μ r_N}. */
	inline Vector3r projectOnCone(const Vector3r& z, Real mu)
	{
		const Real zt = math::sqrt(z[1] * z[1] + z[2] * z[2]);
		if (z[0] >= 0 && zt <= mu * z[0]) return z;    // inside (z_N ≥ 0 matters when μ = 0)
		if (mu * zt <= -z[0] || zt == 0) return Vector3r::Zero(); // inside the polar cone
		const Real a = (mu * zt + z[0]) / (1 + mu * mu); // onto the boundary ray
		return Vector3r(a, mu * a * z[1] / zt, mu * a * z[2] / zt);
	}

	/*! Natural-map residual of one contact, in velocity units:
	 *      e(r, U) = (r − P_{C_μ}(r − ρ Û)) / ρ,   Û = U + μ|U_T| e_N (De Saxcé's modified velocity),
	 *  which vanishes exactly when (r, U) satisfies the Signorini–Coulomb law (Siconos'
	 *  `fc3d_unitary_compute_and_add_error` uses the same map with ρ = 1). With ρ = 1/W_NN the
	 *  residual is a velocity, so dividing by free velocities gives a dimensionless error. */
	inline Vector3r naturalMapResidual(const Vector3r& r, const Vector3r& U, Real mu, Real rho)
	{
		Vector3r Uhat = U;
		Uhat[0] += mu * math::sqrt(U[1] * U[1] + U[2] * U[2]);
		return (r - projectOnCone(r - rho * Uhat, mu)) / rho;
	}

	/*! The sliding branch found by its direction, for any SPD W. With r_T along the unit vector
	 *  d = (cos θ, sin θ) and v = (1, μ d): r = r_N v, and U_N = 0 gives r_N = −b_N / (W v)_N.
	 *  Scaled by the positive (W v)_N, the tangential velocity is V(θ) = −b_N (W v)_T + (W v)_N b_T,
	 *  a trigonometric polynomial of degree 2 without poles; the branch holds where V × d = 0,
	 *  V·d ≤ 0 (slip opposite to r_T) and (W v)_N > 0 (r_N > 0). The at most four roots are
	 *  bracketed on `samples` angles and bisected to rounding; the valid one with the smallest
	 *  law residual is returned (false: none). Used when the coupling iteration of solveLocal
	 *  does not reach the law. */
	inline bool solveSlidingByAngle(const Matrix3r& W, const Vector3r& b, Real mu, Vector3r& r, int samples = 360)
	{
		const Real pi  = 4 * math::atan(Real(1));
		auto       cut = [&](Real th, Real& den, Vector2r& V) { // V × d at θ
			const Real     c = math::cos(th), s = math::sin(th);
			const Vector3r Wv = W * Vector3r(1, mu * c, mu * s);
			den               = Wv[0];
			V                 = Vector2r(-b[0] * Wv[1] + den * b[1], -b[0] * Wv[2] + den * b[2]);
			return V[0] * s - V[1] * c;
		};
		bool     found = false;
		Real     best  = std::numeric_limits<Real>::infinity();
		Real     den;
		Vector2r V;
		Real     lo = 0, glo = cut(lo, den, V);
		for (int k = 1; k <= samples; ++k) {
			const Real hi = 2 * pi * k / samples, ghi = cut(hi, den, V);
			if (glo == 0 || (glo < 0) != (ghi < 0)) { // a root in [lo, hi]: bisect [a, z]
				Real a = lo, ga = glo, z = hi;
				for (int it = 0; it < 200 && ga != 0 && z - a > 4 * std::numeric_limits<Real>::epsilon(); ++it) {
					const Real mid = 0.5 * (a + z), gm = cut(mid, den, V);
					if ((gm < 0) == (ga < 0)) a = mid, ga = gm;
					else z = mid;
				}
				cut(a, den, V);
				const Real c = math::cos(a), s = math::sin(a);
				if (den > 0 && V[0] * c + V[1] * s <= 0) {
					const Real     rn = -b[0] / den;
					const Vector3r cand(rn, mu * rn * c, mu * rn * s);
					const Real     err = naturalMapResidual(cand, W * cand + b, mu, 1 / W(0, 0)).norm();
					if (err < best) best = err, r = cand, found = true;
				}
			}
			lo = hi, glo = ghi;
		}
		return found;
	}

	/*! The sliding branch by Newton's method on its direction d = (cos θ, sin θ), from the unit
	 *  vector d (a warm start: the previous impulse's direction). With v = (1, μ d) as in
	 *  solveSlidingByAngle, g(θ) = V(θ) × d(θ) is a smooth trigonometric polynomial whose derivative
	 *  is closed-form; each step turns d by δ = g/g′ (cosine and sine of small turns by their
	 *  Taylor series). Converged when |δ| ≤ 1e-15; the root must be the branch's: (W v)_N > 0 (so
	 *  r_N > 0 where b_N < 0) and V·d ≤ 0 (slip opposite to r_T). False, and r untouched, when
	 *  Newton does not get there within `maxSteps` (a fold, a wrong root): the caller falls back. */
	inline bool solveSlidingNewton(const Matrix3r& W, const Vector3r& b, Real mu, Real c, Real s, Vector3r& r, int maxSteps = 30)
	{
		const Real bn = b[0];
		for (int k = 0; k < maxSteps; ++k) {
			const Real a = W(0, 0) + mu * (W(0, 1) * c + W(0, 2) * s), da = mu * (W(0, 2) * c - W(0, 1) * s);
			const Real p1 = W(1, 0) + mu * (W(1, 1) * c + W(1, 2) * s), dp1 = mu * (W(1, 2) * c - W(1, 1) * s);
			const Real p2 = W(2, 0) + mu * (W(2, 1) * c + W(2, 2) * s), dp2 = mu * (W(2, 2) * c - W(2, 1) * s);
			const Real V1 = a * b[1] - bn * p1, V2 = a * b[2] - bn * p2; // V = (W v)_N b_T − b_N (W v)_T
			const Real dV1 = da * b[1] - bn * dp1, dV2 = da * b[2] - bn * dp2;
			const Real g = V1 * s - V2 * c, dg = dV1 * s - dV2 * c + V1 * c + V2 * s;
			if (!(dg != 0) || !std::isfinite(g / dg)) return false;
			const Real d = g / dg, d2 = d * d;
			Real       cd, sd; // cos δ, sin δ
			if (math::abs(d) < 1e-3) cd = 1 - d2 * (0.5 - d2 / 24), sd = d * (1 - d2 * (1. / 6 - d2 / 120));
			else cd = math::cos(d), sd = math::sin(d);
			const Real cn = c * cd + s * sd; // θ − δ
			s             = s * cd - c * sd;
			c             = cn;
			if (math::abs(d) > 1e-15) continue;
			const Real aN = W(0, 0) + mu * (W(0, 1) * c + W(0, 2) * s);
			if (!(aN > 0)) return false;
			const Real rn = -bn / aN;
			const Real U1 = b[1] + rn * (W(1, 0) + mu * (W(1, 1) * c + W(1, 2) * s)), U2 = b[2] + rn * (W(2, 0) + mu * (W(2, 1) * c + W(2, 2) * s));
			if (!(rn > 0) || U1 * c + U2 * s > 0) return false;
			r = Vector3r(rn, mu * rn * c, mu * rn * s);
			return true;
		}
		return false;
	}

	/*! Solve the local problem exactly for r (see the file header); returns the status.
	 *
	 *  Open: r = 0 is the solution iff b_N ≥ 0. Sticking: r = −W⁻¹b if that lies in the cone.
	 *  Sliding: r_N = −(b_N + W_NT r_T)/W_NN and r_T = −μ r_N U_T/|U_T|. When the tangential
	 *  block of W is a multiple of the identity and W_NT = 0 (any sphere contact whose bodies
	 *  have isotropic inertia and no blocked DOFs), U_T is parallel to b_T and the sliding
	 *  branch is closed-form; otherwise the coupling terms are iterated to a fixed point
	 *  (at most `maxInner` passes, relative change 1e-14). */
	inline ContactStatus solveLocal(const Matrix3r& W, const Matrix3r& Winv, const Vector3r& b, Real mu, Vector3r& r, int maxInner = 50)
	{
		if (b[0] >= 0) {
			r.setZero();
			return ContactStatus::Open;
		}
		const Vector3r stick = -(Winv * b);
		if (stick[0] > 0 && stick[1] * stick[1] + stick[2] * stick[2] <= mu * mu * stick[0] * stick[0]) {
			r = stick;
			return ContactStatus::Sticking;
		}
		// Sliding. Split W_TT = w I + D (D traceless part), iterate on the coupling terms.
		const Real wt        = 0.5 * (W(1, 1) + W(2, 2));
		const bool decoupled = W(0, 1) == 0 && W(0, 2) == 0 && W(1, 2) == 0 && W(1, 1) == W(2, 2);
		Vector2r   rt = (r[0] > 0) ? Vector2r(r[1], r[2]) : Vector2r::Zero();
		if (!decoupled && mu > 0) {
			// coupled (clump contacts): Newton on the direction, from the previous impulse's or the
			// uncoupled one's (measured on a pile of dimers: 2–4 steps where the fixed point below
			// takes 14 passes on average). A root it returns is the law's by construction (U_N = 0,
			// r on the cone, U_T against r_T; core tests: law residual below 1e-12 on coupled blocks)
			Vector2r d0 = rt;
			if (!(d0.squaredNorm() > 0)) d0 = -Vector2r(b[1] + W(1, 0) * (-b[0] / W(0, 0)), b[2] + W(2, 0) * (-b[0] / W(0, 0)));
			const Real n0 = d0.norm();
			Vector3r   byNewton;
			if (n0 > 0 && solveSlidingNewton(W, b, mu, d0[0] / n0, d0[1] / n0, byNewton)) {
				r = byNewton;
				return ContactStatus::Sliding;
			}
		}
		Real       rn = 0;
		for (int k = 0; k < maxInner; ++k) {
			rn = math::max(Real(0), -(b[0] + W(0, 1) * rt[0] + W(0, 2) * rt[1]) / W(0, 0));
			// tangential velocity without the isotropic self-term: U_T = w r_T + t
			const Vector2r t(
			        b[1] + W(1, 0) * rn + (W(1, 1) - wt) * rt[0] + W(1, 2) * rt[1], b[2] + W(2, 0) * rn + W(2, 1) * rt[0] + (W(2, 2) - wt) * rt[1]);
			const Real tn = t.norm();
			// r_T = −μ r_N U_T/|U_T| with U_T = w r_T + t  ⇒  r_T = −μ r_N t/|t| (when |t| > w μ r_N)
			const Vector2r next = (tn > 0) ? Vector2r(-mu * rn * t / tn) : Vector2r::Zero();
			const Real     dr   = (next - rt).norm();
			rt                  = next;
			if (decoupled || dr <= 1e-14 * (math::abs(rn) + rt.norm())) break;
		}
		r = Vector3r(rn, rt[0], rt[1]);
		if (!decoupled) {
			// strong coupling can stall or cycle the fixed point (measured: about 1 % of random
			// SPD blocks): then the branch is found by its direction
			const Real err = naturalMapResidual(r, W * r + b, mu, 1 / W(0, 0)).norm();
			Vector3r   byAngle;
			if (err > 1e-13 * b.norm() && solveSlidingByAngle(W, b, mu, byAngle)
			    && naturalMapResidual(byAngle, W * byAngle + b, mu, 1 / W(0, 0)).norm() < err) {
				r = byAngle;
				return ContactStatus::Sliding;
			}
		}
		return rn > 0 ? ContactStatus::Sliding : ContactStatus::Open;
	}

	/*! The same local problem when W = diag(d_N, d_T, d_T) (sphere contacts, isotropic bodies):
	 *  every branch closed-form, as in solveLocal's decoupled case. */
	inline ContactStatus solveLocalDiagonal(const Vector3r& d, const Vector3r& b, Real mu, Vector3r& r)
	{
		if (!(b[0] < 0)) { // a NaN offset gives no impulse either: the NaN is reported by its body, not spread
			r.setZero();
			return ContactStatus::Open;
		}
		const Real rn = -b[0] / d[0], r1 = -b[1] / d[1], r2 = -b[2] / d[2];
		if (r1 * r1 + r2 * r2 <= mu * mu * rn * rn) {
			r = Vector3r(rn, r1, r2);
			return ContactStatus::Sticking;
		}
		const Real s = mu * rn / math::sqrt(b[1] * b[1] + b[2] * b[2]);
		r            = Vector3r(rn, -s * b[1], -s * b[2]);
		return ContactStatus::Sliding;
	}

	/*! Same, computing W⁻¹ itself (callers that solve the same W repeatedly pass it in). */
	inline ContactStatus solveLocal(const Matrix3r& W, const Vector3r& b, Real mu, Vector3r& r) { return solveLocal(W, W.inverse(), b, mu, r); }

} // namespace cd
} // namespace yade
