// Contact Dynamics solver core: the order in which a Gauss–Seidel sweep visits the contacts.
//
// A schedule cuts the (permuted) contact set into consecutive ranges, and the ranges into
// consecutive stages. Stages run one after the other; the ranges of a stage share no dynamic
// body, so a parallel stage runs its ranges on several threads at once, each range in order.
// Every pass over the contacts (the sweep, the momentum extrapolation, the position
// correction) runs through Schedule::run, so they all follow one order and one OpenMP pattern.
// Sums over a pass are taken range by range (or contact by contact) in a fixed order: results
// are bit-identical for any thread count.
//
// Strategies (the integrator's sweepOrder):
//   Height  (1)  one range, the contacts upwards by height: a load change at the floor travels up
//                the whole stack in one sweep. The default.
//   Colours (4)  contacts grouped into colours that share no dynamic body (greedy, in height
//                order), one stage per colour, cut into ranges of at most 256 contacts (any cut
//                gives the same result: contacts of a colour commute, and sums are taken contact
//                by contact).
//   Slabs   (5)  vertical slabs of equal contact counts across the wider horizontal extent, each
//                cut (slabsAcross > 1) along the other horizontal axis into columns of equal
//                contact counts: the parts. The contacts inside a part form one range, all parts one
//                parallel stage, followed by the interface: its contacts grouped by the parts their
//                bodies touch; the groups of two parts coloured so that a colour's groups share no
//                part (with slabs only: the even cuts, then the odd ones), one parallel stage per
//                colour, the groups touching three parts or more coloured after them into the
//                same colours where they fit. With ownBodies, every dynamic body is owned by
//                one part instead (the one holding most of its contacts): a part's range holds
//                the contacts between its own bodies (or with obstacles), and the interface the
//                contacts between bodies of two parts, grouped by that pair: a smaller
//                interface, and no groups of three parts (docs/scale-out.md).
// Retired (measured worse, docs/results.md): 0 by ids, 2 alternating up and down, 3 downwards.
#pragma once

#include "Problem.hpp"

namespace yade {
namespace cd {

	class Schedule {
	public:
		enum Kind { Height = 1, Colours = 4, Slabs = 5 };
		/*! Stages [begin, end) of ranges; parallel: its ranges may run on several threads. */
		struct Stage {
			int  begin, end;
			bool parallel;
		};
		std::vector<long>  bounds; // range i is contacts [bounds[i], bounds[i+1])
		std::vector<Stage> stages;
		bool               sumPerContact = false; // sums over a pass are taken contact by contact (Colours), not range by range
		int                nColours = 0;   // Colours: colours used (65: an overflow group exists)
		int                nInterface = 0; // Slabs: contacts not inside one part (swept after the parts)
		int                nWide      = 0; // Slabs: interface contacts touching three parts or more (coloured after the two-part groups)

		int ranges() const { return int(bounds.size()) - 1; }
		/*! Run every stage on the calling thread, ranges in their order (the same results: the
		 *  ranges of a parallel stage share no dynamic body). */
		void serial()
		{
			for (Stage& st : stages)
				st.parallel = false;
		}

		/*! Build the schedule of the given kind, permuting the set's contacts into its order
		 *  (slabs, across, ownBodies: the parts of Slabs and how bodies are assigned to them;
		 *  ignored by the other kinds). */
		void build(int kind, ContactSet& set, const std::vector<BodyRecord>& records, int slabs, int across, bool ownBodies, const Vector3r& up);

		/*! Call f(range, begin, end) for every range, stage by stage, the ranges of a parallel
		 *  stage on all threads. */
		template <class F> void run(F&& f) const
		{
			for (const Stage& st : stages) {
				if (!st.parallel) { // a serial stage runs on the calling thread, outside any parallel region
					for (int i = st.begin; i < st.end; ++i)
						f(i, bounds[i], bounds[i + 1]);
					continue;
				}
#pragma omp parallel for schedule(static)
				for (int i = st.begin; i < st.end; ++i)
					f(i, bounds[i], bounds[i + 1]);
			}
		}
		/*! The same with the stages in reverse order; the ranges of a stage are handed out as in
		 *  run(), and f itself decides the direction it walks its range (the position correction's
		 *  downward sweeps walk each range from its end). */
		template <class F> void runBackwards(F&& f) const
		{
			for (auto st = stages.rbegin(); st != stages.rend(); ++st) {
				if (!st->parallel) {
					for (int i = st->begin; i < st->end; ++i)
						f(i, bounds[i], bounds[i + 1]);
					continue;
				}
#pragma omp parallel for schedule(static)
				for (int i = st->begin; i < st->end; ++i)
					f(i, bounds[i], bounds[i + 1]);
			}
		}

	private:
		void byHeight(long nc);
		void colours(ContactSet& set, const std::vector<BodyRecord>& records);
		void slabs(ContactSet& set, const std::vector<BodyRecord>& records, int ns, int across, bool ownBodies, const Vector3r& up);
	};

} // namespace cd
} // namespace yade
