#pragma once
// XDMF (v3) sidecars that make grainwave's HDF5 files open directly in ParaView: one temporal
// collection per output kind (particles.xmf, fields.xmf), each step pointing at its HDF5 file.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace grainwave::io {

/// One array of a grid: an HDF5 dataset of `rows` x `components` values.
struct XdmfArray {
  std::string name;
  std::string dataset;   ///< "file.h5:/particles/velocity"
  int components = 1;    ///< 1 scalar, 3 vector
  std::string number_type = "Float";  ///< Float or Int
  int precision = 8;
};

/// A point cloud (particles): Polyvertex topology with XYZ geometry from `positions`.
std::string polyvertex_grid(const std::string& name, long count, const std::string& positions,
                            const std::vector<XdmfArray>& point_arrays);

/// A uniform patch (one block of the adaptive grid): 2D/3D CoRectMesh of `points` per axis
/// (x, y, z order) at `origin` with `spacing`; arrays are node-centred with C order (z, y, x).
std::string uniform_patch_grid(const std::string& name, int dimension,
                               const std::vector<long>& points, const std::vector<double>& origin,
                               const std::vector<double>& spacing,
                               const std::vector<XdmfArray>& node_arrays);

/// Several grids shown together at one time (e.g. all blocks of a grid).
std::string spatial_collection(const std::string& name, const std::vector<std::string>& grids);

/// A time series, rewritten atomically after every step added.
class XdmfTimeSeries {
 public:
  explicit XdmfTimeSeries(std::filesystem::path path) : path_(std::move(path)) {}
  void add(double time, const std::string& grid_xml);
  void write() const;
  const std::filesystem::path& path() const { return path_; }
  /// The steps as one string, for checkpoints; restore() takes it back.
  std::string serialise() const;
  void restore(const std::string& serialised);
  std::size_t size() const { return steps_.size(); }

 private:
  std::filesystem::path path_;
  std::vector<std::pair<double, std::string>> steps_;
};

}  // namespace grainwave::io
