#pragma once
// Parallel HDF5 files for fields, particles and checkpoints.
//
// Every collective call must be made by all ranks of the file's communicator in the same order.
// Distributed datasets are 1D [N] or 2D [N, components], each rank writing its contiguous rows
// at the offset given by the ranks before it, so a file's content does not depend on the number
// of ranks that wrote it. Files are created under a temporary name and renamed by commit().
#include <hdf5.h>
#include <mpi.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace grainwave::io {

/// Owns one HDF5 identifier (file, group, dataset, dataspace, property list...).
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(Handle&& o) noexcept : id_(o.id_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  hid_t get() const { return id_; }
  void reset();

 private:
  hid_t id_ = H5I_INVALID_HID;
};

class Hdf5Group {
 public:
  Hdf5Group(hid_t id, MPI_Comm comm) : handle_(id), comm_(comm) {}
  hid_t id() const { return handle_.get(); }
  MPI_Comm comm() const { return comm_; }

  Hdf5Group create_group(const std::string& name);  // collective
  Hdf5Group open_group(const std::string& name) const;
  bool has(const std::string& name) const;
  /// Names of the objects directly in this group.
  std::vector<std::string> children() const;

  // Attributes (collective when writing; every rank passes the same value).
  void set_attribute(const std::string& name, double value);
  void set_attribute(const std::string& name, std::int64_t value);
  void set_attribute(const std::string& name, const std::string& value);
  bool has_attribute(const std::string& name) const;
  double real_attribute(const std::string& name) const;
  std::int64_t integer_attribute(const std::string& name) const;
  std::string text_attribute(const std::string& name) const;

  /// Collective: writes a [N_total, components] dataset (1D when components == 1) from each
  /// rank's `rows` rows. Returns N_total.
  std::int64_t write_rows(const std::string& name, const double* data, std::size_t rows,
                          std::size_t components = 1);
  std::int64_t write_rows(const std::string& name, const std::int64_t* data, std::size_t rows,
                          std::size_t components = 1);
  /// Collective: stores text of any length (attributes are limited to 64 KiB) as a byte
  /// dataset; every rank passes the same text, rank 0 writes it.
  void write_text(const std::string& name, const std::string& text);
  std::string read_text(const std::string& name) const;
  /// Dataset shape ({N} or {N, components}).
  std::vector<std::uint64_t> shape(const std::string& name) const;
  /// Reads rows [first, first + count) of a dataset (independent I/O).
  std::vector<double> read_rows_real(const std::string& name, std::uint64_t first,
                                     std::uint64_t count) const;
  std::vector<std::int64_t> read_rows_integer(const std::string& name, std::uint64_t first,
                                              std::uint64_t count) const;

 private:
  Handle handle_;
  MPI_Comm comm_;
};

class Hdf5File {
 public:
  /// Collective: creates the temporary file for `final_path`.
  static Hdf5File create(const std::filesystem::path& final_path, MPI_Comm comm = MPI_COMM_WORLD);
  /// Collective: opens an existing file read-only; throws InputError if it is not an HDF5 file.
  static Hdf5File open_read(const std::filesystem::path& path, MPI_Comm comm = MPI_COMM_WORLD);

  Hdf5File(Hdf5File&&) noexcept = default;
  ~Hdf5File();

  Hdf5Group& root() { return root_; }
  const Hdf5Group& root() const { return root_; }
  const std::filesystem::path& path() const { return path_; }
  /// Collective: closes the file and renames it to its final name.
  void commit();

 private:
  Hdf5File(Handle file, hid_t root, std::filesystem::path path, MPI_Comm comm, bool writing);
  Handle file_;
  Hdf5Group root_;
  std::filesystem::path path_;
  MPI_Comm comm_;
  bool writing_ = false;
};

/// Quiets HDF5's own error printing; grainwave reports errors itself. Call once at start-up.
void silence_hdf5_errors();

}  // namespace grainwave::io
