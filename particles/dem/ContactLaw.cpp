#include "particles/dem/ContactLaw.hpp"

#include "core/Error.hpp"

namespace grainwave::particles::dem {

// grainwave_particles is a static archive, so a law's object file (and the registrar inside it)
// is linked only when something references it. These anchors pull in the built-in laws; they
// can go once the library is linked whole (WHOLE_ARCHIVE or an OBJECT library).
extern const bool kLinearSpringDashpotRegistered;
extern const bool kHertzNormalRegistered;
extern const bool kStaticFrictionRegistered;
extern const bool kCoulombSpringRegistered;
extern const bool kMindlinRegistered;

namespace {
bool builtin_laws_linked() {
  const volatile bool* anchors[] = {&kLinearSpringDashpotRegistered, &kHertzNormalRegistered,
                                    &kStaticFrictionRegistered, &kCoulombSpringRegistered,
                                    &kMindlinRegistered};
  bool all = true;
  for (const volatile bool* anchor : anchors) all = all && *anchor;
  return all;
}
}  // namespace

template <class Law>
std::unique_ptr<Law> LawRegistry<Law>::create(const std::string& name,
                                              const LawParameters& parameters) const {
  builtin_laws_linked();
  const auto it = factories_.find(name);
  if (it == factories_.end()) {
    std::string known;
    for (const auto& entry : factories_) known += (known.empty() ? "" : ", ") + entry.first;
    throw InputError({"contact model", 0}, name, "unknown contact law", "known laws: " + known);
  }
  auto law = it->second(parameters);
  parameters.check_all_used(name);
  return law;
}

template class LawRegistry<NormalLaw>;
template class LawRegistry<TangentialLaw>;

LawRegistry<NormalLaw>& normal_law_registry() {
  static LawRegistry<NormalLaw> registry;
  return registry;
}

LawRegistry<TangentialLaw>& tangential_law_registry() {
  static LawRegistry<TangentialLaw> registry;
  return registry;
}

ContactModel make_contact_model(const std::string& normal_name, const LawParameters& normal_parameters,
                                const std::string& tangential_name,
                                const LawParameters& tangential_parameters) {
  ContactModel model;
  model.normal = normal_law_registry().create(normal_name, normal_parameters);
  model.tangential = tangential_law_registry().create(tangential_name, tangential_parameters);
  return model;
}

}  // namespace grainwave::particles::dem
