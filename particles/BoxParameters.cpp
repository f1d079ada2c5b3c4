#include "particles/BoxParameters.hpp"

#include <fmt/format.h>

namespace grainwave::particles {

namespace {
const std::vector<std::string> kFaceKinds = {"periodic", "wall", "open"};
const char* kBoundaryKeys[] = {"boundary_x", "boundary_y", "boundary_z"};

FaceKind face_kind(const std::string& s) {
  if (s == "wall") return FaceKind::kWall;
  if (s == "open") return FaceKind::kOpen;
  return FaceKind::kPeriodic;
}

Eigen::Vector3d vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }
}  // namespace

void declare_box(SectionDecl& s, const BoxDefaults& defaults) {
  const std::string unit = defaults.length_unit;
  s.integer("dimension", 3, "2: disks in the x-y plane (unit depth); 3: spheres").in_range(2, 3);
  s.reals("box_lo", std::nullopt, "lower corner of the box" + unit).of_length(3);
  s.reals("box_hi", std::nullopt, "upper corner of the box" + unit).of_length(3);
  for (int k = 0; k < 3; ++k)
    s.texts(kBoundaryKeys[k], std::vector<std::string>{"periodic", "periodic"},
            fmt::format("kind of the low and high {} faces (wall: rigid plane; open: particles "
                        "leaving are removed)",
                        "xyz"[k]))
        .one_of(kFaceKinds)
        .of_length(2);
  s.reals("gravity", defaults.gravity,
          "gravitational acceleration" + (unit.empty() ? std::string() : std::string(" [m/s^2]")))
      .of_length(3);
}

Domain read_box(const SceneSection& s, Eigen::Vector3d& gravity) {
  Domain domain;
  domain.dimension = static_cast<int>(s.integer("dimension"));
  domain.lo = vec3(s.reals("box_lo"));
  domain.hi = vec3(s.reals("box_hi"));
  for (int k = 0; k < domain.dimension; ++k)
    if (domain.hi[k] <= domain.lo[k])
      s.fail("box_hi", "the box must have box_hi > box_lo along every axis");
  for (int k = 0; k < 3; ++k) {
    const auto& faces = s.texts(kBoundaryKeys[k]);
    const FaceKind lo = face_kind(faces[0]), hi = face_kind(faces[1]);
    if ((lo == FaceKind::kPeriodic) != (hi == FaceKind::kPeriodic))
      s.fail(kBoundaryKeys[k], "a periodic face needs a periodic opposite face");
    domain.face[static_cast<std::size_t>(k)] = {lo, hi};
  }
  gravity = vec3(s.reals("gravity"));
  if (domain.dimension == 2 && gravity.z() != 0)
    s.fail("gravity", "a 2D scene needs gravity with z = 0");
  return domain;
}

}  // namespace grainwave::particles
