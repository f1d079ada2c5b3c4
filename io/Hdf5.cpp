#include "io/Hdf5.hpp"

#include <stdexcept>

#include "core/Error.hpp"
#include "core/Mpi.hpp"
#include "io/AtomicFile.hpp"

namespace grainwave::io {

namespace fs = std::filesystem;

namespace {
hid_t check(hid_t id, const std::string& what) {
  if (id < 0) throw std::runtime_error("HDF5: cannot " + what);
  return id;
}
void check_status(herr_t status, const std::string& what) {
  if (status < 0) throw std::runtime_error("HDF5: cannot " + what);
}
Handle collective_transfer() {
  Handle dxpl(check(H5Pcreate(H5P_DATASET_XFER), "create transfer list"));
  check_status(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), "set collective transfer");
  return dxpl;
}
}  // namespace

void silence_hdf5_errors() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

Handle& Handle::operator=(Handle&& o) noexcept {
  if (this != &o) {
    reset();
    id_ = o.id_;
    o.id_ = H5I_INVALID_HID;
  }
  return *this;
}

void Handle::reset() {
  if (id_ >= 0 && H5Iis_valid(id_) > 0) H5Idec_ref(id_);
  id_ = H5I_INVALID_HID;
}

// ---------------------------------------------------------------------------------------------
// Groups and attributes

Hdf5Group Hdf5Group::create_group(const std::string& name) {
  return Hdf5Group(check(H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                         "create group " + name),
                   comm_);
}

Hdf5Group Hdf5Group::open_group(const std::string& name) const {
  return Hdf5Group(check(H5Gopen2(id(), name.c_str(), H5P_DEFAULT), "open group " + name), comm_);
}

bool Hdf5Group::has(const std::string& name) const {
  return H5Lexists(id(), name.c_str(), H5P_DEFAULT) > 0;
}

std::vector<std::string> Hdf5Group::children() const {
  std::vector<std::string> names;
  auto collect = [](hid_t, const char* name, const H5L_info_t*, void* out) -> herr_t {
    static_cast<std::vector<std::string>*>(out)->push_back(name);
    return 0;
  };
  H5Literate(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names);
  return names;
}

namespace {
void write_scalar_attribute(hid_t obj, const std::string& name, hid_t type, const void* value) {
  if (H5Aexists(obj, name.c_str()) > 0) H5Adelete(obj, name.c_str());
  Handle space(check(H5Screate(H5S_SCALAR), "create scalar space"));
  Handle attr(check(H5Acreate2(obj, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                    "create attribute " + name));
  check_status(H5Awrite(attr.get(), type, value), "write attribute " + name);
}
}  // namespace

void Hdf5Group::set_attribute(const std::string& name, double value) {
  write_scalar_attribute(id(), name, H5T_NATIVE_DOUBLE, &value);
}

void Hdf5Group::set_attribute(const std::string& name, std::int64_t value) {
  write_scalar_attribute(id(), name, H5T_NATIVE_INT64, &value);
}

void Hdf5Group::set_attribute(const std::string& name, const std::string& value) {
  Handle type(check(H5Tcopy(H5T_C_S1), "copy string type"));
  H5Tset_size(type.get(), value.empty() ? 1 : value.size());
  H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
  write_scalar_attribute(id(), name, type.get(), value.empty() ? "" : value.data());
}

bool Hdf5Group::has_attribute(const std::string& name) const {
  return H5Aexists(id(), name.c_str()) > 0;
}

double Hdf5Group::real_attribute(const std::string& name) const {
  Handle attr(check(H5Aopen(id(), name.c_str(), H5P_DEFAULT), "open attribute " + name));
  double v = 0;
  check_status(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &v), "read attribute " + name);
  return v;
}

std::int64_t Hdf5Group::integer_attribute(const std::string& name) const {
  Handle attr(check(H5Aopen(id(), name.c_str(), H5P_DEFAULT), "open attribute " + name));
  std::int64_t v = 0;
  check_status(H5Aread(attr.get(), H5T_NATIVE_INT64, &v), "read attribute " + name);
  return v;
}

std::string Hdf5Group::text_attribute(const std::string& name) const {
  Handle attr(check(H5Aopen(id(), name.c_str(), H5P_DEFAULT), "open attribute " + name));
  Handle type(check(H5Aget_type(attr.get()), "get attribute type"));
  if (H5Tget_class(type.get()) != H5T_STRING)
    throw std::runtime_error("HDF5: attribute " + name + " is not a string");
  const std::size_t n = H5Tget_size(type.get());
  std::string s(n, '\0');
  check_status(H5Aread(attr.get(), type.get(), s.data()), "read attribute " + name);
  s.resize(s.find('\0') == std::string::npos ? n : s.find('\0'));
  return s;
}

// ---------------------------------------------------------------------------------------------
// Distributed datasets

namespace {
std::int64_t write_distributed(hid_t group, MPI_Comm comm, const std::string& name, hid_t type,
                               const void* data, std::size_t rows, std::size_t components) {
  const auto local = static_cast<std::int64_t>(rows);
  const std::int64_t total = mpi::sum(local, comm);
  const std::int64_t offset = mpi::exclusive_prefix_sum(local, comm);
  const int rank = components > 1 ? 2 : 1;
  const hsize_t dims[2] = {static_cast<hsize_t>(total), static_cast<hsize_t>(components)};
  Handle file_space(check(H5Screate_simple(rank, dims, nullptr), "create dataspace"));
  Handle dataset(check(H5Dcreate2(group, name.c_str(), type, file_space.get(), H5P_DEFAULT,
                                  H5P_DEFAULT, H5P_DEFAULT),
                       "create dataset " + name));
  const hsize_t start[2] = {static_cast<hsize_t>(offset), 0};
  const hsize_t count[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(components)};
  Handle mem_space(check(H5Screate_simple(rank, count, nullptr), "create memory space"));
  if (rows > 0) {
    check_status(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count,
                                     nullptr),
                 "select rows");
  } else {
    H5Sselect_none(file_space.get());
    H5Sselect_none(mem_space.get());
  }
  Handle dxpl = collective_transfer();
  check_status(H5Dwrite(dataset.get(), type, mem_space.get(), file_space.get(), dxpl.get(), data),
               "write dataset " + name);
  return total;
}

template <class T>
std::vector<T> read_distributed(hid_t group, const std::string& name, hid_t type,
                                std::uint64_t first, std::uint64_t count) {
  Handle dataset(check(H5Dopen2(group, name.c_str(), H5P_DEFAULT), "open dataset " + name));
  Handle file_space(check(H5Dget_space(dataset.get()), "get dataspace"));
  const int rank = H5Sget_simple_extent_ndims(file_space.get());
  hsize_t dims[2] = {0, 1};
  H5Sget_simple_extent_dims(file_space.get(), dims, nullptr);
  if (first + count > dims[0])
    throw std::runtime_error("HDF5: rows out of range in dataset " + name);
  const hsize_t components = rank == 2 ? dims[1] : 1;
  std::vector<T> out(static_cast<std::size_t>(count * components));
  const hsize_t start[2] = {first, 0};
  const hsize_t n[2] = {count, components};
  Handle mem_space(check(H5Screate_simple(rank, n, nullptr), "create memory space"));
  if (count > 0) {
    H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, n, nullptr);
  } else {
    H5Sselect_none(file_space.get());
    H5Sselect_none(mem_space.get());
  }
  check_status(H5Dread(dataset.get(), type, mem_space.get(), file_space.get(), H5P_DEFAULT,
                       out.data()),
               "read dataset " + name);
  return out;
}
}  // namespace

std::int64_t Hdf5Group::write_rows(const std::string& name, const double* data, std::size_t rows,
                                   std::size_t components) {
  return write_distributed(id(), comm_, name, H5T_NATIVE_DOUBLE, data, rows, components);
}

std::int64_t Hdf5Group::write_rows(const std::string& name, const std::int64_t* data,
                                   std::size_t rows, std::size_t components) {
  return write_distributed(id(), comm_, name, H5T_NATIVE_INT64, data, rows, components);
}

void Hdf5Group::write_text(const std::string& name, const std::string& text) {
  if (text.empty()) return;  // a zero-length dataset cannot be written; read_text gives ""
  const bool root = mpi::rank(comm_) == 0;
  write_distributed(id(), comm_, name, H5T_NATIVE_CHAR, text.data(), root ? text.size() : 0, 1);
}

std::string Hdf5Group::read_text(const std::string& name) const {
  if (!has(name)) return {};
  const auto n = shape(name).at(0);
  auto bytes = read_distributed<char>(id(), name, H5T_NATIVE_CHAR, 0, n);
  return {bytes.begin(), bytes.end()};
}

std::vector<std::uint64_t> Hdf5Group::shape(const std::string& name) const {
  Handle dataset(check(H5Dopen2(id(), name.c_str(), H5P_DEFAULT), "open dataset " + name));
  Handle space(check(H5Dget_space(dataset.get()), "get dataspace"));
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank > 0 ? rank : 0));
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  return {dims.begin(), dims.end()};
}

std::vector<double> Hdf5Group::read_rows_real(const std::string& name, std::uint64_t first,
                                              std::uint64_t count) const {
  return read_distributed<double>(id(), name, H5T_NATIVE_DOUBLE, first, count);
}

std::vector<std::int64_t> Hdf5Group::read_rows_integer(const std::string& name,
                                                       std::uint64_t first,
                                                       std::uint64_t count) const {
  return read_distributed<std::int64_t>(id(), name, H5T_NATIVE_INT64, first, count);
}

// ---------------------------------------------------------------------------------------------
// Files

Hdf5File::Hdf5File(Handle file, hid_t root, fs::path path, MPI_Comm comm, bool writing)
    : file_(std::move(file)),
      root_(root, comm),
      path_(std::move(path)),
      comm_(comm),
      writing_(writing) {}

namespace {
Handle mpio_access(MPI_Comm comm) {
  Handle fapl(check(H5Pcreate(H5P_FILE_ACCESS), "create access list"));
  check_status(H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL), "set MPI-IO driver");
  return fapl;
}
}  // namespace

Hdf5File Hdf5File::create(const fs::path& final_path, MPI_Comm comm) {
  Handle fapl = mpio_access(comm);
  const fs::path tmp = temporary_path(final_path);
  const hid_t id = H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (id < 0) throw std::runtime_error("cannot create HDF5 file " + tmp.string());
  Handle file(id);
  const hid_t root = check(H5Gopen2(id, "/", H5P_DEFAULT), "open root group");
  return Hdf5File(std::move(file), root, final_path, comm, true);
}

Hdf5File Hdf5File::open_read(const fs::path& path, MPI_Comm comm) {
  if (!fs::exists(path)) throw InputError({path.string(), 0}, "", "no such file");
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw InputError({path.string(), 0}, "", "not an HDF5 file (or truncated)");
  Handle fapl = mpio_access(comm);
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl.get());
  if (id < 0) throw InputError({path.string(), 0}, "", "cannot open HDF5 file");
  Handle file(id);
  const hid_t root = check(H5Gopen2(id, "/", H5P_DEFAULT), "open root group");
  return Hdf5File(std::move(file), root, path, comm, false);
}

void Hdf5File::commit() {
  root_ = Hdf5Group(H5I_INVALID_HID, comm_);
  // A file with objects still open is not closed by H5Fclose (close degree SEMI under MPI-IO);
  // renaming it then would publish an incomplete file, so this is checked, not assumed.
  const hid_t id = file_.get();
  const auto open_objects = H5Fget_obj_count(id, H5F_OBJ_DATASET | H5F_OBJ_GROUP |
                                                     H5F_OBJ_DATATYPE | H5F_OBJ_ATTR);
  if (open_objects != 0)
    throw std::logic_error("HDF5: " + path_.string() + " committed with " +
                           std::to_string(open_objects) + " objects still open");
  const herr_t closed = H5Fclose(id);
  file_ = Handle();
  if (closed < 0) throw std::runtime_error("HDF5: cannot close " + path_.string());
  MPI_Barrier(comm_);
  if (mpi::rank(comm_) == 0) commit_temporary(path_);
  MPI_Barrier(comm_);
  writing_ = false;
}

Hdf5File::~Hdf5File() {
  // An uncommitted file (an exception while writing) stays under its temporary name only.
  root_ = Hdf5Group(H5I_INVALID_HID, comm_);
  file_.reset();
}

}  // namespace grainwave::io
