#include "io/Xdmf.hpp"

#include <fmt/format.h>

#include <sstream>

#include "io/AtomicFile.hpp"

namespace grainwave::io {

namespace {
std::string data_item(const XdmfArray& a, const std::string& dims) {
  return fmt::format(
      "        <DataItem Dimensions=\"{}\" NumberType=\"{}\" Precision=\"{}\" "
      "Format=\"HDF\">{}</DataItem>\n",
      dims, a.number_type, a.precision, a.dataset);
}
std::string attribute(const XdmfArray& a, const std::string& dims) {
  return fmt::format("      <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"Node\">\n{}"
                     "      </Attribute>\n",
                     a.name, a.components == 1 ? "Scalar" : "Vector", data_item(a, dims));
}
}  // namespace

std::string polyvertex_grid(const std::string& name, long count, const std::string& positions,
                            const std::vector<XdmfArray>& point_arrays) {
  std::string xml = fmt::format(
      "    <Grid Name=\"{}\" GridType=\"Uniform\">\n"
      "      <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"{}\" "
      "NodesPerElement=\"1\"/>\n"
      "      <Geometry GeometryType=\"XYZ\">\n{}      </Geometry>\n",
      name, count, data_item({"position", positions, 3}, fmt::format("{} 3", count)));
  for (const auto& a : point_arrays)
    xml += attribute(a, a.components == 1 ? fmt::format("{}", count)
                                          : fmt::format("{} {}", count, a.components));
  return xml + "    </Grid>\n";
}

std::string uniform_patch_grid(const std::string& name, int dimension,
                               const std::vector<long>& points, const std::vector<double>& origin,
                               const std::vector<double>& spacing,
                               const std::vector<XdmfArray>& node_arrays) {
  // XDMF lists dimensions slowest first (z y x) and origin/spacing in the same order.
  std::string dims, org, sp;
  for (int k = dimension - 1; k >= 0; --k) {
    const auto ku = static_cast<std::size_t>(k);
    dims += fmt::format("{}{}", dims.empty() ? "" : " ", points[ku]);
    org += fmt::format("{}{}", org.empty() ? "" : " ", origin[ku]);
    sp += fmt::format("{}{}", sp.empty() ? "" : " ", spacing[ku]);
  }
  const std::string topo = dimension == 3 ? "3DCoRectMesh" : "2DCoRectMesh";
  const std::string geo = dimension == 3 ? "ORIGIN_DXDYDZ" : "ORIGIN_DXDY";
  std::string xml = fmt::format(
      "    <Grid Name=\"{}\" GridType=\"Uniform\">\n"
      "      <Topology TopologyType=\"{}\" Dimensions=\"{}\"/>\n"
      "      <Geometry GeometryType=\"{}\">\n"
      "        <DataItem Dimensions=\"{}\" Format=\"XML\">{}</DataItem>\n"
      "        <DataItem Dimensions=\"{}\" Format=\"XML\">{}</DataItem>\n"
      "      </Geometry>\n",
      name, topo, dims, geo, dimension, org, dimension, sp);
  for (const auto& a : node_arrays)
    xml += attribute(a, a.components == 1 ? dims : fmt::format("{} {}", dims, a.components));
  return xml + "    </Grid>\n";
}

std::string spatial_collection(const std::string& name, const std::vector<std::string>& grids) {
  std::string xml =
      fmt::format("    <Grid Name=\"{}\" GridType=\"Collection\" CollectionType=\"Spatial\">\n",
                  name);
  for (const auto& g : grids) xml += g;
  return xml + "    </Grid>\n";
}

void XdmfTimeSeries::add(double time, const std::string& grid_xml) {
  steps_.emplace_back(time, grid_xml);
}

void XdmfTimeSeries::write() const {
  std::ostringstream out;
  out << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
      << "<Xdmf Version=\"3.0\">\n  <Domain>\n"
      << "  <Grid Name=\"series\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const auto& [time, grid] : steps_) {
    // The Time element must be the first child of each step's grid.
    const auto close = grid.find(">\n");
    out << grid.substr(0, close + 2) << fmt::format("      <Time Value=\"{}\"/>\n", time)
        << grid.substr(close + 2);
  }
  out << "  </Grid>\n  </Domain>\n</Xdmf>\n";
  write_text_atomically(path_, out.str());
}

std::string XdmfTimeSeries::serialise() const {
  std::string s;
  for (const auto& [time, grid] : steps_) s += fmt::format("{}\n{}\n{}\x1e", time, grid.size(), grid);
  return s;
}

void XdmfTimeSeries::restore(const std::string& serialised) {
  steps_.clear();
  std::size_t pos = 0;
  while (pos < serialised.size()) {
    const auto a = serialised.find('\n', pos);
    const auto b = serialised.find('\n', a + 1);
    const double time = std::stod(serialised.substr(pos, a - pos));
    const auto length = static_cast<std::size_t>(std::stoull(serialised.substr(a + 1, b - a - 1)));
    steps_.emplace_back(time, serialised.substr(b + 1, length));
    pos = b + 1 + length + 1;
  }
}

}  // namespace grainwave::io
