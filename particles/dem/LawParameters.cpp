#include "particles/dem/LawParameters.hpp"

#include "core/Error.hpp"

namespace grainwave::particles::dem {

double LawParameters::get(const std::string& key, std::string_view law) const {
  const auto it = values_.find(key);
  if (it == values_.end())
    throw InputError({"contact law '" + std::string(law) + "'", 0}, key, "missing parameter");
  used_.insert(key);
  return it->second;
}

double LawParameters::get_or(const std::string& key, double fallback) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return fallback;
  used_.insert(key);
  return it->second;
}

void LawParameters::check_all_used(std::string_view law) const {
  for (const auto& [key, value] : values_) {
    if (used_.count(key) == 0)
      throw InputError({"contact law '" + std::string(law) + "'", 0}, key, "unknown parameter");
  }
}

}  // namespace grainwave::particles::dem
