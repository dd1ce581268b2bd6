// Contact Dynamics solver core: problem files (see ProblemFile.hpp for the layout).
#include "ProblemFile.hpp"

#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace yade {
namespace cd {

	namespace {
		void put(std::ostream& o, const Vector3r& v) { o << ' ' << v[0] << ' ' << v[1] << ' ' << v[2]; }
		void put(std::ostream& o, const Matrix3r& m)
		{
			for (int i = 0; i < 3; ++i)
				for (int j = 0; j < 3; ++j)
					o << ' ' << m(i, j);
		}

		// Reads the numbers of one line, naming the line when one is missing or malformed.
		struct LineReader {
			std::istringstream s;
			long               lineNo;
			std::string        line;
			LineReader(const std::string& text, long no)
			        : s(text)
			        , lineNo(no)
			        , line(text)
			{
			}
			[[noreturn]] void fail(const std::string& what) const
			{
				throw std::runtime_error("problem file, line " + std::to_string(lineNo) + ": " + what + " in \"" + line.substr(0, 80) + "\"");
			}
			template <class T> T get()
			{
				T v;
				if (!(s >> v)) fail("a missing or malformed number");
				return v;
			}
			Vector3r vec()
			{
				Vector3r v; // one by one: the order of evaluation of a call's arguments is unspecified
				for (int i = 0; i < 3; ++i)
					v[i] = get<Real>();
				return v;
			}
			Matrix3r mat()
			{
				Matrix3r m;
				for (int i = 0; i < 3; ++i)
					for (int j = 0; j < 3; ++j)
						m(i, j) = get<Real>();
				return m;
			}
			void keyword(const std::string& k)
			{
				std::string w;
				if (!(s >> w) || w != k) fail("expected \"" + k + "\"");
			}
			bool more()
			{
				s >> std::ws;
				return !s.eof();
			}
			void end()
			{
				std::string rest;
				if (s >> rest) fail("unexpected \"" + rest + "\"");
			}
		};
	}

	void writeProblem(std::ostream& out, const Solver& solver, const Params& p)
	{
		std::ostringstream o;
		o.precision(std::numeric_limits<Real>::max_digits10);
		o << "cdproblem 1\n";
		o << "params " << p.h;
		put(o, p.up);
		o << ' ' << p.tolerance << ' ' << p.maxIter << ' ' << p.checkEvery << ' ' << p.relaxation << ' ' << p.schedule << ' ' << p.slabs << ' '
		  << int(p.momentum) << ' ' << int(p.sphereFastPath) << ' ' << p.positionTolerance << ' ' << p.maxProjectionIter;
		// optional trailing fields, written up to the last that departs from its default
		// (absent: correctionMomentum 0, slabsAcross 1, slabsOwnBodies 0)
		const int trailing = p.slabsOwnBodies ? 3 : p.slabsAcross != 1 ? 2 : p.correctionMomentum ? 1 : 0;
		if (trailing >= 1) o << ' ' << int(p.correctionMomentum);
		if (trailing >= 2) o << ' ' << p.slabsAcross;
		if (trailing >= 3) o << ' ' << int(p.slabsOwnBodies);
		o << '\n';
		o << "bodies " << solver.bodies.size() << '\n';
		for (size_t id = 0; id < solver.bodies.size(); ++id) {
			const Body&       b = solver.bodies[id];
			const BodyRecord& r = solver.records[id];
			o << "body " << id << ' ' << int(r.dynamic) << ' ' << r.isoInvM << ' ' << r.isoInvI;
			put(o, b.v);
			put(o, b.w);
			put(o, b.invM);
			put(o, b.invI);
			put(o, r.vi);
			put(o, r.wi);
			o << '\n';
		}
		const ContactSet& set = solver.contacts;
		o << "contacts " << set.size() << '\n';
		for (size_t k = 0; k < set.size(); ++k) {
			const ContactInfo& c = set.info[k];
			o << "contact " << c.b1 << ' ' << c.b2 << ' ' << set.state[k].mu << ' ' << set.state[k].status;
			put(o, c.frame);
			put(o, c.c1);
			put(o, c.c2);
			put(o, c.point);
			o << ' ' << c.height << ' ' << c.gapI << ' ' << c.gapM << ' ' << c.refR << ' ' << c.allowance << ' ' << c.en << ' ' << c.et;
			put(o, c.approach);
			put(o, c.warmStart);
			if (c.shifted) put(o, c.shift); // body 2 through its periodic image: an optional trailing shift velocity
			o << '\n';
		}
		out << o.str();
	}

	SavedProblem readProblem(std::istream& in)
	{
		SavedProblem pb;
		std::string  text;
		long         no = 0;
		auto next = [&](const char* what) -> LineReader {
			if (!std::getline(in, text)) throw std::runtime_error("problem file: ends before " + std::string(what) + " (line " + std::to_string(no + 1) + ")");
			return LineReader(text, ++no);
		};
		{
			LineReader l = next("the header");
			l.keyword("cdproblem");
			if (l.get<int>() != 1) l.fail("unknown format version (this core reads 1)");
		}
		{
			LineReader l = next("the parameters");
			Params&    p = pb.params;
			l.keyword("params");
			p.h                 = l.get<Real>();
			p.up                = l.vec();
			p.tolerance         = l.get<Real>();
			p.maxIter           = l.get<int>();
			p.checkEvery        = l.get<int>();
			p.relaxation        = l.get<Real>();
			p.schedule          = l.get<int>();
			p.slabs             = l.get<int>();
			p.momentum          = l.get<int>() != 0;
			p.sphereFastPath      = l.get<int>() != 0;
			p.positionTolerance = l.get<Real>();
			p.maxProjectionIter = l.get<int>();
			// files written before the correction had momentum end here: they were solved without it
			p.correctionMomentum = l.more() ? l.get<int>() != 0 : false;
			// ... and before the slabs had columns: slabs only
			p.slabsAcross = l.more() ? l.get<int>() : 1;
			// ... and before bodies could be owned by parts: a body's contacts decide nothing
			p.slabsOwnBodies = l.more() ? l.get<int>() != 0 : false;
			l.end();
		}
		LineReader hb = next("the body count");
		hb.keyword("bodies");
		const long nb = hb.get<long>();
		if (nb < 0) hb.fail("a negative body count");
		pb.bodies.resize(nb);
		pb.records.resize(nb);
		for (long id = 0; id < nb; ++id) {
			LineReader l = next("a body");
			l.keyword("body");
			if (l.get<long>() != id) l.fail("bodies out of order");
			Body&       b = pb.bodies[id];
			BodyRecord& r = pb.records[id];
			r.dynamic     = l.get<int>() != 0;
			r.isoInvM     = l.get<Real>();
			r.isoInvI     = l.get<Real>();
			b.v           = l.vec();
			b.w           = l.vec();
			b.invM        = l.vec();
			b.invI        = l.mat();
			r.vi          = l.vec();
			r.wi          = l.vec();
			l.end();
		}
		LineReader hc = next("the contact count");
		hc.keyword("contacts");
		const long nc = hc.get<long>();
		if (nc < 0) hc.fail("a negative contact count");
		for (long k = 0; k < nc; ++k) {
			LineReader  l = next("a contact");
			ContactInfo c;
			l.keyword("contact");
			c.b1            = l.get<int>();
			c.b2            = l.get<int>();
			const Real mu   = l.get<Real>();
			const int  st   = l.get<int>();
			c.frame         = l.mat();
			c.c1            = l.vec();
			c.c2            = l.vec();
			c.point         = l.vec();
			c.height        = l.get<Real>();
			c.gapI          = l.get<Real>();
			c.gapM          = l.get<Real>();
			c.refR          = l.get<Real>();
			c.allowance     = l.get<Real>();
			c.en            = l.get<Real>();
			c.et            = l.get<Real>();
			c.approach      = l.vec();
			c.warmStart     = l.vec();
			c.origin        = k;
			if (l.more()) { // a periodic image's shift velocity (absent: body 2 itself)
				c.shifted = true;
				c.shift   = l.vec();
			}
			l.end();
			if (c.b1 < 0 || c.b1 >= nb || c.b2 < 0 || c.b2 >= nb || c.b1 == c.b2) l.fail("a contact between unknown bodies");
			pb.contacts.add(c, mu, st);
		}
		while (std::getline(in, text))
			if (!text.empty()) pb.extra.push_back(text);
		return pb;
	}

	SavedProblem readProblemFile(const std::string& path)
	{
		std::ifstream f(path);
		if (!f) throw std::runtime_error("problem file " + path + ": cannot be opened");
		try {
			return readProblem(f);
		} catch (const std::runtime_error& e) {
			throw std::runtime_error(path + ": " + e.what());
		}
	}

	void SavedProblem::load(Solver& solver) const
	{
		solver.bodies   = bodies;
		solver.records  = records;
		solver.contacts = contacts;
	}

} // namespace cd
} // namespace yade
