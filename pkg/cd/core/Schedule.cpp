// Contact Dynamics solver core: the sweep schedules (see Schedule.hpp).
#include "Schedule.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace yade {
namespace cd {

	void Schedule::build(int kind, ContactSet& set, const std::vector<BodyRecord>& records, int ns, const Vector3r& up)
	{
		nColours = nInterface = nSerial = 0;
		sumPerContact         = false;
		switch (kind) {
			case Height: byHeight(long(set.size())); break;
			case Colours: colours(set, records); break;
			case Slabs: slabs(set, records, ns, up); break;
			default: throw std::invalid_argument("cd::Schedule: unknown kind " + std::to_string(kind) + " (1 height, 4 colours, 5 slabs).");
		}
	}

	void Schedule::byHeight(long nc)
	{
		bounds = { 0, nc };
		stages = { Stage { 0, 1, false } };
	}

	// Greedy colouring in the contacts' (height) order: the smallest colour not yet taken by a
	// contact of either dynamic body (obstacles never conflict: nothing writes them). Contacts
	// of one colour share no dynamic body, so their updates commute. Colours past 63 form one
	// last group swept by one thread. The contacts are then stored colour by colour, by body ids
	// within a colour (neighbouring contacts touch neighbouring bodies in memory).
	void Schedule::colours(ContactSet& set, const std::vector<BodyRecord>& records)
	{
		constexpr int  maxColours        = 64;
		constexpr long minParallelColour = 64; // below this a colour is swept by one thread (a parallel region costs a few µs)
		const long     nc                = long(set.size());
		std::vector<uint64_t> taken(records.size(), 0);
		std::vector<int>      colour(nc);
		std::vector<long>     count(maxColours + 1, 0);
		for (long k = 0; k < nc; ++k) {
			const int      b1 = set.info[k].b1, b2 = set.info[k].b2;
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
		std::vector<long> start(maxColours + 2, 0);
		for (int c = 0; c <= maxColours; ++c)
			start[c + 1] = start[c] + count[c];
		std::vector<long> next(start.begin(), start.end() - 1), order(nc);
		for (long k = 0; k < nc; ++k)
			order[next[colour[k]]++] = k;
		for (int c = 0; c <= maxColours; ++c)
			std::sort(order.begin() + start[c], order.begin() + start[c + 1], [&set](long a, long b) {
				const ContactInfo &ca = set.info[a], &cb = set.info[b];
				return ca.b1 < cb.b1 || (ca.b1 == cb.b1 && ca.b2 < cb.b2);
			});
		set.permute(order);
		// one stage per non-empty colour, cut into ranges of at most maxRange contacts
		constexpr long maxRange = 256;
		bounds.assign(1, 0);
		stages.clear();
		for (int c = 0; c <= maxColours; ++c) {
			if (!count[c]) continue;
			const int first = ranges();
			for (long b = start[c]; b < start[c + 1]; b += maxRange)
				bounds.push_back(std::min(b + maxRange, start[c + 1]));
			stages.push_back(Stage { first, ranges(), c < maxColours && count[c] >= minParallelColour });
			nColours = c + 1;
		}
		sumPerContact = true;
	}

	// Slabs: the contact points cut, across the wider horizontal extent, into ns slabs of equal
	// contact counts. A contact is inner when each of its dynamic bodies has all its contacts in
	// the contact's slab; inner contacts of different slabs then share no body and their slabs
	// can be swept at the same time. The rest (contacts of bodies that straddle a cut) form the
	// interface, swept after the slabs: the contacts whose bodies have all their contacts in the
	// two slabs beside one cut belong to that cut, and cuts two apart share no body, so the even
	// cuts are swept at the same time, then the odd ones; what spans more than two slabs (bodies
	// wider than a slab) is swept last by one thread. Height order is kept within every group.
	// With two slabs there is one cut and nothing spans more: the order is the same as with a
	// single serial interface.
	void Schedule::slabs(ContactSet& set, const std::vector<BodyRecord>& records, int ns, const Vector3r& up)
	{
		if (ns < 1 || ns > 64) throw std::invalid_argument("cd::Schedule: slabs=" + std::to_string(ns) + " must lie in 1..64.");
		const long nc    = long(set.size());
		auto       point = [&set](long k) -> const Vector3r& { return set.info[k].point; };
		int        axis  = 0;
		Real       width = -1;
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
		std::vector<uint64_t> touched(records.size(), 0);
		for (long k = 0; k < nc; ++k) {
			group[k]     = int(std::upper_bound(cut.begin(), cut.end(), x[k]) - cut.begin());
			const int b1 = set.info[k].b1, b2 = set.info[k].b2;
			if (records[b1].dynamic) touched[b1] |= uint64_t(1) << group[k];
			if (records[b2].dynamic) touched[b2] |= uint64_t(1) << group[k];
		}
		// groups: slabs 0..ns−1 (inner), then the cuts, even ones first (cut c lies between
		// slabs c and c+1), then the serial rest: consecutive, so that each stage's ranges are
		const int         nGroups = 2 * ns, nCuts = ns - 1, nEven = (nCuts + 1) / 2;
		auto              cutGroup = [&](int c) { return ns + (c % 2 == 0 ? c / 2 : nEven + c / 2); };
		std::vector<long> count(nGroups, 0);
		for (long k = 0; k < nc; ++k) {
			const uint64_t own = uint64_t(1) << group[k];
			const int      b1 = set.info[k].b1, b2 = set.info[k].b2;
			const uint64_t span = own | (records[b1].dynamic ? touched[b1] : 0) | (records[b2].dynamic ? touched[b2] : 0);
			if (span != own) {
				const int lo = __builtin_ctzll(span);
				group[k]     = (span >> lo) == 3 ? cutGroup(lo) : nGroups - 1; // exactly slabs lo and lo+1: that cut's
			}
			++count[group[k]];
		}
		bounds.assign(nGroups + 1, 0);
		for (int g = 0; g < nGroups; ++g)
			bounds[g + 1] = bounds[g] + count[g];
		std::vector<long> next(bounds.begin(), bounds.end() - 1), order(nc);
		for (long k = 0; k < nc; ++k)
			order[next[group[k]]++] = k;
		set.permute(order);
		nInterface = int(nc - bounds[ns]);
		nSerial    = int(count[nGroups - 1]);
		// a stage runs in parallel when it has several ranges and enough contacts to pay for a
		// parallel region
		auto stage = [&](int first, int last) { return Stage { first, last, last - first > 1 && bounds[last] - bounds[first] >= 256 }; };
		stages     = { stage(0, ns), stage(ns, ns + nEven), stage(ns + nEven, ns + nCuts), stage(ns + nCuts, nGroups) };
	}

} // namespace cd
} // namespace yade
