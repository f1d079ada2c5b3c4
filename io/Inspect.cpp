#include "io/Inspect.hpp"

#include <fmt/format.h>
#include <hdf5.h>

#include "io/Hdf5.hpp"

namespace grainwave::io {

namespace {
std::string attribute_value(hid_t attr) {
  Handle type(H5Aget_type(attr));
  Handle space(H5Aget_space(attr));
  const auto cls = H5Tget_class(type.get());
  if (H5Sget_simple_extent_npoints(space.get()) != 1) return "(array)";
  if (cls == H5T_STRING) {
    std::string s(H5Tget_size(type.get()), '\0');
    H5Aread(attr, type.get(), s.data());
    s.resize(s.find('\0') == std::string::npos ? s.size() : s.find('\0'));
    if (s.size() > 72 || s.find('\n') != std::string::npos)
      return fmt::format("({} characters of text)", s.size());
    return "\"" + s + "\"";
  }
  if (cls == H5T_INTEGER) {
    long long v = 0;
    H5Aread(attr, H5T_NATIVE_LLONG, &v);
    return std::to_string(v);
  }
  if (cls == H5T_FLOAT) {
    double v = 0;
    H5Aread(attr, H5T_NATIVE_DOUBLE, &v);
    return fmt::format("{:.10g}", v);
  }
  return "(?)";
}

struct Listing {
  std::string text;
};

herr_t list_attribute(hid_t obj, const char* name, const H5A_info_t*, void* data) {
  auto* out = static_cast<Listing*>(data);
  Handle attr(H5Aopen(obj, name, H5P_DEFAULT));
  out->text += fmt::format("    @{} = {}\n", name, attribute_value(attr.get()));
  return 0;
}

herr_t list_object(hid_t root, const char* name, const H5O_info_t* info, void* data) {
  auto* out = static_cast<Listing*>(data);
  if (std::string(name) == ".") return 0;
  if (info->type == H5O_TYPE_GROUP) {
    out->text += fmt::format("  /{}/\n", name);
  } else if (info->type == H5O_TYPE_DATASET) {
    Handle ds(H5Dopen2(root, name, H5P_DEFAULT));
    Handle space(H5Dget_space(ds.get()));
    Handle type(H5Dget_type(ds.get()));
    hsize_t dims[8] = {};
    const int rank = H5Sget_simple_extent_ndims(space.get());
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    std::string shape;
    for (int i = 0; i < rank; ++i) shape += fmt::format("{}{}", i ? " x " : "", dims[i]);
    const auto cls = H5Tget_class(type.get());
    const char* kind = cls == H5T_FLOAT ? "real" : cls == H5T_INTEGER ? "integer" : "other";
    out->text += fmt::format("  /{}  [{}] {}\n", name, shape, kind);
  }
  Handle obj(H5Oopen(root, name, H5P_DEFAULT));
  H5Aiterate2(obj.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, list_attribute, out);
  return 0;
}
}  // namespace

std::string describe_hdf5_file(const std::filesystem::path& path) {
  auto file = Hdf5File::open_read(path, MPI_COMM_SELF);
  const auto& root = file.root();
  Listing listing;
  const std::string kind =
      root.has_attribute("grainwave_kind") ? root.text_attribute("grainwave_kind") : "unknown";
  listing.text += fmt::format("{}: grainwave {} file\n", path.string(), kind);
  H5Aiterate2(root.id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, list_attribute, &listing);
  H5Ovisit(root.id(), H5_INDEX_NAME, H5_ITER_INC, list_object, &listing);
  return listing.text;
}

}  // namespace grainwave::io
