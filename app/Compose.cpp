#include "app/Compose.hpp"

#include "app/Simulation.hpp"
#include "fluid/FluidSystem.hpp"
#include "particles/ParticleSystem.hpp"
#include "wavelet/WaveletSystem.hpp"
#include "particles/dem/DemSystem.hpp"

namespace grainwave::app {

const SceneSchema& scene_schema() {
  static const SceneSchema schema = [] {
    SceneSchema s;
    Simulation::declare(s);
    particles::ParticleSystem::declare(s);
    wavelet::WaveletSystem::declare(s);
    particles::dem::DemSystem::declare(s);
    fluid::FluidSystem::declare(s);
    return s;
  }();
  return schema;
}

std::unique_ptr<io::System> compose_system(const Scene& scene) {
  if (scene.has("particles")) return std::make_unique<particles::ParticleSystem>(scene);
  if (scene.has("fluid")) return fluid::FluidSystem::create(scene);
  if (scene.has("wavelet")) return wavelet::WaveletSystem::create(scene);
  if (scene.has("dem")) return std::make_unique<particles::dem::DemSystem>(scene);
  throw InputError({scene.file(), 0}, "",
                   "the scene declares no physics to run: add a [fluid], [particles], [dem] or "
                   "[wavelet] section",
                   "see docs/scene-reference.md");
}

std::vector<std::string> modules_built(const Scene& scene) {
  std::vector<std::string> lines;
  const auto& schema = scene_schema();
  for (const auto& name : scene.present_sections()) {
    const auto* decl = schema.find(name);
    lines.push_back("[" + name + "] " + decl->doc);
  }
  return lines;
}

}  // namespace grainwave::app
