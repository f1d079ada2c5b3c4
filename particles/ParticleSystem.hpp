#pragma once
// Particles on their own: free flight under constant body forces (002 Eqs 2.9-2.13),
//   x(t+dt) = x + v dt + F/(2m) dt^2,  v(t+dt) = v + F/m dt,  omega(t+dt) = omega + T/I dt,
// in a box whose faces are periodic, walls or open (particles leaving an open face are removed
// and counted). Built from the scene's [particles] section (and [[particle]] entries).
//
// Distribution over MPI ranks: every rank generates the same global initial list and keeps a
// contiguous slice of it; output is ordered by particle id, so files do not depend on the
// number of ranks.
#include <cstdint>
#include <random>
#include <string>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"
#include "io/Xdmf.hpp"
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

namespace grainwave::particles {

class ParticleSystem : public io::System {
 public:
  static void declare(SceneSchema& schema);
  explicit ParticleSystem(const Scene& scene);

  std::string describe() const override;
  double max_stable_dt() const override;
  void advance(double t, double dt) override;
  std::optional<std::string> check_state() const override;
  void save_good_state() override { good_ = store_; good_removed_ = removed_; }
  void restore_good_state() override { store_ = good_; removed_ = good_removed_; }
  std::vector<io::OutputGrid> write_output(io::Hdf5File& file, const std::string& file_name) override;
  void write_checkpoint(io::Hdf5Group& group) override;
  void read_checkpoint(const io::Hdf5Group& group) override;
  void report(io::Json& counts, io::Json& metrics, double step_wall_s, long steps) const override;
  std::size_t memory_bytes() const override;
  std::string progress_note() const override;

  const ParticleStore& store() const { return store_; }
  const Domain& domain() const { return domain_; }

  /// Global totals (collective): translational + rotational kinetic energy, linear momentum.
  double kinetic_energy() const;
  Vec3 linear_momentum() const;

 private:
  void place_initial_particles(const Scene& scene);
  void apply_boundaries();
  std::int64_t global_count() const;

  Domain domain_;
  Vec3 gravity_ = Vec3::Zero();
  ParticleStore store_, good_;
  std::int64_t removed_ = 0, good_removed_ = 0;  ///< particles that left through open faces
  std::int64_t initial_count_ = 0;
  double initial_energy_ = 0;
  Vec3 initial_momentum_ = Vec3::Zero();
};

}  // namespace grainwave::particles
