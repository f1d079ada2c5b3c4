#pragma once
// The two halves of a DEM contact law (002 Eq. 3.3 splits the contact force into a normal and a
// tangential part) and the registries that build them by name.
//
// A law is called once per force evaluation on the whole batch of active contacts: the virtual
// call is per batch, while the per-contact force is an inline member of the `final` concrete law
// looping over the batch, so there is no virtual call per pair. The normal law runs first and
// writes Contact::normal_force; the tangential law then reads it (Coulomb limit) and writes
// Contact::tangential_force. Each law registers itself under a name in its own .cpp file.
#include "particles/dem/Contact.hpp"
#include "particles/dem/LawParameters.hpp"

#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace grainwave::particles::dem {

class ContactHistory;

/// Which part of a time step a force evaluation belongs to; decides how tangential history moves.
enum class HistoryStage {
  kSingle,   ///< one evaluation per step (velocity Verlet): advance and commit the history
  kPredict,  ///< first RK2 stage at t_n: use the committed history, remember v_t
  kCorrect,  ///< second RK2 stage at t_n+dt: use the predicted history, commit the trapezoid
};

class NormalLaw {
 public:
  virtual ~NormalLaw() = default;
  /// Writes normal_force for every contact of the batch.
  virtual void evaluate(std::span<Contact> contacts) const = 0;
  /// Duration of a binary collision with effective mass m* and radius R* (sets the time step).
  virtual double contact_duration(double effective_mass, double effective_radius) const = 0;
};

class TangentialLaw {
 public:
  virtual ~TangentialLaw() = default;
  /// Whether contacts need a ContactHistoryEntry (a stored tangential displacement).
  virtual bool needs_history() const = 0;
  /// Writes tangential_force for every contact; may read and update each contact's history.
  virtual void evaluate(std::span<Contact> contacts, HistoryStage stage, double dt) const = 0;
};

/// Name -> factory map for one kind of law. Factories read their keys from LawParameters.
template <class Law>
class LawRegistry {
 public:
  using Factory = std::function<std::unique_ptr<Law>(const LawParameters&)>;

  /// Returns true so that a namespace-scope `const bool` can register at static initialisation.
  bool add(const std::string& name, Factory factory) {
    factories_[name] = std::move(factory);
    return true;
  }
  bool contains(const std::string& name) const { return factories_.count(name) != 0; }
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const auto& entry : factories_) out.push_back(entry.first);
    return out;
  }
  /// Builds the law `name`; throws InputError listing the known names when it is not registered.
  std::unique_ptr<Law> create(const std::string& name, const LawParameters& parameters) const;

 private:
  std::map<std::string, Factory> factories_;
};

LawRegistry<NormalLaw>& normal_law_registry();
LawRegistry<TangentialLaw>& tangential_law_registry();

/// A normal and a tangential law used together.
struct ContactModel {
  std::shared_ptr<const NormalLaw> normal;
  std::shared_ptr<const TangentialLaw> tangential;
};

/// Builds a ContactModel by names; each parameter bag must be fully used by its law.
ContactModel make_contact_model(const std::string& normal_name, const LawParameters& normal_parameters,
                                const std::string& tangential_name,
                                const LawParameters& tangential_parameters);

}  // namespace grainwave::particles::dem
