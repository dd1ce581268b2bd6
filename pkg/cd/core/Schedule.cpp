// Contact Dynamics solver core: the sweep schedules (see Schedule.hpp).
#include "Schedule.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace yade {
namespace cd {

	void Schedule::build(int kind, ContactSet& set, const std::vector<BodyRecord>& records, int ns, int across, bool ownBodies, const Vector3r& up)
	{
		nColours = nInterface = nWide = 0;
		sumPerContact         = false;
		switch (kind) {
			case Height: byHeight(long(set.size())); break;
			case Colours: colours(set, records); break;
			case Slabs: slabs(set, records, ns, across, ownBodies, up); break;
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

	namespace {
		// The part of every contact (Schedule::slabs): its slab across the wider horizontal
		// extent (ns slabs of equal contact counts), then (across > 1) its column along the other
		// horizontal axis within the slab (across columns of equal counts); numbered slab by slab.
		std::vector<int> cutIntoParts(const ContactSet& set, int ns, int across, const Vector3r& up)
		{
			const long       nc = long(set.size());
			std::vector<int> part(nc);
			auto             point      = [&set](long k) -> const Vector3r& { return set.info[k].point; };
			auto             horizontal = [&up](int a) { return math::abs(up[a]) <= 0.5; }; // not along gravity
			Real             extent[3];
			for (int a = 0; a < 3; ++a) {
				Real lo = std::numeric_limits<Real>::infinity(), hi = -lo;
				for (long k = 0; k < nc; ++k)
					lo = math::min(lo, point(k)[a]), hi = math::max(hi, point(k)[a]);
				extent[a] = nc ? hi - lo : 0;
			}
			// the slabs' axis: the widest horizontal one; the columns': the wider of the other
			// horizontal axes, else of the other axes
			int  axis = 0, other = -1;
			Real width = -1;
			for (int a = 0; a < 3; ++a)
				if (horizontal(a) && extent[a] > width) width = extent[a], axis = a;
			for (int a = 0; a < 3; ++a)
				if (a != axis && (other < 0 || horizontal(a) > horizontal(other) || (horizontal(a) == horizontal(other) && extent[a] > extent[other])))
					other = a;
			{
				std::vector<Real> x(nc);
				for (long k = 0; k < nc; ++k)
					x[k] = point(k)[axis];
				std::vector<Real> sorted(x);
				std::sort(sorted.begin(), sorted.end());
				std::vector<Real> cut(ns - 1);
				for (int s = 1; s < ns; ++s)
					cut[s - 1] = sorted[size_t(s) * nc / ns];
				for (long k = 0; k < nc; ++k)
					part[k] = int(std::upper_bound(cut.begin(), cut.end(), x[k]) - cut.begin()) * across;
			}
			if (across > 1) {
				std::vector<std::vector<Real>> y(ns);
				for (long k = 0; k < nc; ++k)
					y[part[k] / across].push_back(point(k)[other]);
				std::vector<std::vector<Real>> cut(ns);
				for (int s = 0; s < ns; ++s) {
					std::sort(y[s].begin(), y[s].end());
					for (int c = 1; c < across && !y[s].empty(); ++c)
						cut[s].push_back(y[s][size_t(c) * y[s].size() / across]);
				}
				for (long k = 0; k < nc; ++k) {
					const std::vector<Real>& c = cut[part[k] / across];
					part[k] += int(std::upper_bound(c.begin(), c.end(), point(k)[other]) - c.begin());
				}
			}
			return part;
		}

		// The part that owns each dynamic body: the one that holds most of its contacts, the lowest
		// on a tie (-1 for obstacles and bodies without contacts). The parts of each body's
		// contacts are listed body by body (a counting sort), then sorted and counted.
		std::vector<int> ownerOfBodies(const ContactSet& set, const std::vector<BodyRecord>& records, const std::vector<int>& part)
		{
			const long       nc = long(set.size());
			const size_t     nb = records.size();
			std::vector<int> start(nb + 1, 0), owner(nb, -1);
			for (long k = 0; k < nc; ++k)
				for (int b : { set.info[k].b1, set.info[k].b2 })
					if (records[b].dynamic) ++start[b + 1];
			for (size_t b = 0; b < nb; ++b)
				start[b + 1] += start[b];
			std::vector<int> fill(start.begin(), start.end() - 1), parts(start[nb]);
			for (long k = 0; k < nc; ++k)
				for (int b : { set.info[k].b1, set.info[k].b2 })
					if (records[b].dynamic) parts[fill[b]++] = part[k];
			for (size_t b = 0; b < nb; ++b) {
				const auto first = parts.begin() + start[b], last = parts.begin() + start[b + 1];
				std::sort(first, last);
				long most = 0;
				for (auto run = first; run != last;) {
					const auto end = std::upper_bound(run, last, *run);
					if (end - run > most) most = end - run, owner[b] = *run; // ascending: the lowest part wins a tie
					run = end;
				}
			}
			return owner;
		}

		// Each contact's key, the set of parts its sweep must not run beside (a bit per part):
		// with parts touched, its own part and every part its dynamic bodies touch; with bodies
		// owned, the owners of its dynamic bodies (its own part if it has none: nothing writes
		// it). A contact whose key is one part is inner, swept in that part.
		std::vector<uint64_t> contactKeys(const ContactSet& set, const std::vector<BodyRecord>& records, const std::vector<int>& part, bool ownBodies)
		{
			const long            nc = long(set.size());
			std::vector<uint64_t> key(nc);
			if (ownBodies) {
				const std::vector<int> owner = ownerOfBodies(set, records, part);
				for (long k = 0; k < nc; ++k) {
					const int o1 = records[set.info[k].b1].dynamic ? owner[set.info[k].b1] : -1;
					const int o2 = records[set.info[k].b2].dynamic ? owner[set.info[k].b2] : -1;
					key[k]       = (o1 >= 0 ? uint64_t(1) << o1 : 0) | (o2 >= 0 ? uint64_t(1) << o2 : 0);
					if (!key[k]) key[k] = uint64_t(1) << part[k];
				}
				return key;
			}
			std::vector<uint64_t> touched(records.size(), 0);
			for (long k = 0; k < nc; ++k) {
				const int b1 = set.info[k].b1, b2 = set.info[k].b2;
				if (records[b1].dynamic) touched[b1] |= uint64_t(1) << part[k];
				if (records[b2].dynamic) touched[b2] |= uint64_t(1) << part[k];
			}
			for (long k = 0; k < nc; ++k) {
				const int b1 = set.info[k].b1, b2 = set.info[k].b2;
				key[k]       = (uint64_t(1) << part[k]) | (records[b1].dynamic ? touched[b1] : 0) | (records[b2].dynamic ? touched[b2] : 0);
			}
			return key;
		}
	} // namespace

	// Slabs: the contact points cut, across the wider horizontal extent, into ns slabs of equal
	// contact counts, and (across > 1) every slab cut along the other horizontal axis into
	// `across` columns of equal contact counts (a k-d split: the columns of neighbouring slabs
	// need not line up). Parts are numbered slab by slab. A contact is inner when each of its
	// dynamic bodies has all its contacts in the contact's part; inner contacts of different
	// parts then share no body and their parts can be swept at the same time. The rest (contacts
	// of bodies that straddle a cut) form the interface, swept after the parts, grouped by the
	// set of parts their bodies touch (its key): two contacts that share a body have keys that
	// share that body's parts, so groups with disjoint keys share no body. The groups are
	// coloured greedily, first those of two parts, then those of three parts or more (bodies at a
	// corner, or wider than a part), each class by its lowest part, then by key, so that the
	// groups of one colour have disjoint keys: one parallel stage per colour, and the colours too
	// small for threads (one group, or little beyond the largest) after them as one serial stage.
	// Height order is kept within every group. With slabs only (across = 1) the groups of two
	// parts are the cuts, and their colours the even cuts and the odd ones; with two slabs there
	// is one cut and nothing spans more: the order is the same as with a single serial interface.
	// With ownBodies every dynamic body belongs to one part instead, the one holding most of its
	// contacts; a contact is inner when its dynamic bodies have one owner, and the interface is
	// the contacts between bodies of two parts, grouped by that pair (disjoint pairs share no
	// body): fewer contacts than the bodies straddling a cut have, and no group of three parts.
	void Schedule::slabs(ContactSet& set, const std::vector<BodyRecord>& records, int ns, int across, bool ownBodies, const Vector3r& up)
	{
		if (ns < 1 || across < 1 || ns * across > 64)
			throw std::invalid_argument("cd::Schedule: slabs=" + std::to_string(ns) + ", slabsAcross=" + std::to_string(across)
			                            + ": both must be at least 1 and their product (the parts) at most 64.");
		const long             nc     = long(set.size());
		const int              nParts = ns * across;
		const std::vector<int>      part   = cutIntoParts(set, ns, across, up);
		const std::vector<uint64_t> key    = contactKeys(set, records, part, ownBodies);
		std::vector<int>            home(nc); // the part an inner contact is swept in, else -1
		for (long k = 0; k < nc; ++k)
			home[k] = __builtin_popcountll(key[k]) == 1 ? __builtin_ctzll(key[k]) : -1;
		// the interface groups: the distinct keys of more than one part, those of two parts first,
		// each class by its lowest part, then by key
		auto before = [](uint64_t a, uint64_t b) {
			const bool wa = __builtin_popcountll(a) > 2, wb = __builtin_popcountll(b) > 2;
			if (wa != wb) return wb;
			const int la = __builtin_ctzll(a), lb = __builtin_ctzll(b);
			return la < lb || (la == lb && a < b);
		};
		std::vector<uint64_t> keys;
		for (long k = 0; k < nc; ++k)
			if (home[k] < 0) keys.push_back(key[k]);
		std::sort(keys.begin(), keys.end(), before);
		keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
		// greedy colouring, each group (the pairs first, then the wide ones) into the first colour
		// none of whose groups shares a part with it
		std::vector<uint64_t> colourParts;
		std::vector<int>      colourOf(keys.size());
		for (size_t i = 0; i < keys.size(); ++i) {
			size_t c = 0;
			while (c < colourParts.size() && (colourParts[c] & keys[i]))
				++c;
			if (c == colourParts.size()) colourParts.push_back(0);
			colourParts[c] |= keys[i];
			colourOf[i] = int(c);
		}
		// contacts per key and per colour. The parts' stage runs in parallel when it has several
		// ranges and enough contacts to pay for a parallel region; a colour does when the
		// contacts of its ranges beyond the largest, which threads could take off the critical
		// path, pay for the meeting of the threads (≈ 3 µs, some 64 contact updates). The colours
		// that do not are swept after those that do, in their order, as one serial stage.
		constexpr long   minParallel = 256, minSpare = 64;
		const int        nColours = int(colourParts.size()), nGroups = nParts + int(keys.size());
		std::vector<int> keyOf(nc, -1);
		std::vector<long> keyCount(keys.size(), 0), colourCount(nColours, 0), colourRanges(nColours, 0), colourLargest(nColours, 0);
		std::vector<long> partCount(nParts, 0);
		nWide = 0;
		for (long k = 0; k < nc; ++k) {
			if (home[k] >= 0) {
				++partCount[home[k]];
				continue;
			}
			keyOf[k] = int(std::lower_bound(keys.begin(), keys.end(), key[k], before) - keys.begin());
			++keyCount[keyOf[k]];
			nWide += __builtin_popcountll(key[k]) > 2;
		}
		for (size_t i = 0; i < keys.size(); ++i) {
			const int c = colourOf[i];
			colourCount[c] += keyCount[i], ++colourRanges[c], colourLargest[c] = std::max(colourLargest[c], keyCount[i]);
		}
		auto parallelColour = [&](int c) { return colourRanges[c] > 1 && colourCount[c] - colourLargest[c] >= minSpare; };
		std::vector<int> colourOrder; // the parallel colours, then the serial ones
		for (int pass = 0; pass < 2; ++pass)
			for (int c = 0; c < nColours; ++c)
				if (parallelColour(c) == (pass == 0)) colourOrder.push_back(c);
		// groups: the parts (inner), then the interface groups colour by colour in that order (in
		// key order within a colour): consecutive, so that each stage's ranges are
		std::vector<int> keyGroup(keys.size()), colourStart(nColours + 1, 0), rank(nColours);
		for (int r = 0; r < nColours; ++r)
			rank[colourOrder[r]] = r;
		colourStart[0] = nParts;
		for (int r = 0; r < nColours; ++r)
			colourStart[r + 1] = colourStart[r] + int(colourRanges[colourOrder[r]]);
		{
			std::vector<int> next(colourStart.begin(), colourStart.end() - 1);
			for (size_t i = 0; i < keys.size(); ++i)
				keyGroup[i] = next[rank[colourOf[i]]]++;
		}
		std::vector<long> count(nGroups, 0);
		for (int g = 0; g < nParts; ++g)
			count[g] = partCount[g];
		for (size_t i = 0; i < keys.size(); ++i)
			count[keyGroup[i]] = keyCount[i];
		bounds.assign(nGroups + 1, 0);
		for (int g = 0; g < nGroups; ++g)
			bounds[g + 1] = bounds[g] + count[g];
		std::vector<long> next(bounds.begin(), bounds.end() - 1), order(nc);
		for (long k = 0; k < nc; ++k)
			order[next[keyOf[k] < 0 ? home[k] : keyGroup[keyOf[k]]]++] = k;
		set.permute(order);
		nInterface = int(nc - bounds[nParts]);
		stages.assign(1, Stage { 0, nParts, nParts > 1 && bounds[nParts] >= minParallel });
		int r = 0;
		for (; r < nColours && parallelColour(colourOrder[r]); ++r)
			stages.push_back(Stage { colourStart[r], colourStart[r + 1], true });
		if (r < nColours) stages.push_back(Stage { colourStart[r], colourStart[nColours], false }); // the serial colours
	}

} // namespace cd
} // namespace yade
