#pragma once
// What a scene can contain and what it builds. Every module declares its own sections here;
// a scene composes only the systems whose sections it contains.
#include <memory>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"

namespace grainwave::app {

/// The full schema: every section any module declares.
const SceneSchema& scene_schema();

/// Builds the system a scene describes (throws InputError if it describes none).
std::unique_ptr<io::System> compose_system(const Scene& scene);

/// The modules a scene builds, one line each (for `grainwave check`).
std::vector<std::string> modules_built(const Scene& scene);

}  // namespace grainwave::app
