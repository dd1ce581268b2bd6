// Contact Dynamics solver core: the contact set's bookkeeping (see Problem.hpp).
#include "Problem.hpp"

#include <algorithm>

namespace yade {
namespace cd {

	void ContactSet::clear()
	{
		info.clear();
		state.clear();
		sphere.clear();
		general.clear();
	}

	void ContactSet::resize(size_t n)
	{
		info.resize(n);
		state.resize(n);
		sphere.resize(n);
	}

	void ContactSet::add(const ContactInfo& c, Real mu_, int status_)
	{
		info.push_back(c);
		state.push_back(ContactState { Vector3r::Zero(), mu_, status_, -1 });
		sphere.emplace_back();
	}

	namespace {
		template <class T> void permuteArray(std::vector<T>& a, const std::vector<long>& order)
		{
			std::vector<T> sorted;
			sorted.reserve(a.size());
			for (long k : order)
				sorted.push_back(std::move(a[k]));
			a.swap(sorted);
		}
	}

	void ContactSet::permute(const std::vector<long>& order)
	{
		permuteArray(info, order);
		permuteArray(state, order);
		permuteArray(sphere, order);
	}

} // namespace cd
} // namespace yade
