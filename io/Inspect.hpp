#pragma once
// `grainwave info FILE.h5`: a readable description of any grainwave HDF5 file (output,
// checkpoint, curtain state): its kind, attributes and every dataset with its shape.
#include <filesystem>
#include <string>

namespace grainwave::io {
std::string describe_hdf5_file(const std::filesystem::path& path);
}
