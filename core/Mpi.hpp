#pragma once
// Thin MPI helpers. grainwave runs on MPI_COMM_WORLD; every collective used by the modules goes
// through here so single-rank and multi-rank runs share one code path.
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

namespace grainwave::mpi {

/// Initialises MPI for the lifetime of the object (no-op if already initialised).
class Session {
 public:
  Session(int* argc, char*** argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

 private:
  bool owns_ = false;
};

int rank(MPI_Comm comm = MPI_COMM_WORLD);
int size(MPI_Comm comm = MPI_COMM_WORLD);
inline bool is_root(MPI_Comm comm = MPI_COMM_WORLD) { return rank(comm) == 0; }

double sum(double local, MPI_Comm comm = MPI_COMM_WORLD);
double max(double local, MPI_Comm comm = MPI_COMM_WORLD);
double min(double local, MPI_Comm comm = MPI_COMM_WORLD);
std::int64_t sum(std::int64_t local, MPI_Comm comm = MPI_COMM_WORLD);
std::int64_t max(std::int64_t local, MPI_Comm comm = MPI_COMM_WORLD);
/// Sum over ranks below this one (exclusive prefix sum); 0 on rank 0.
std::int64_t exclusive_prefix_sum(std::int64_t local, MPI_Comm comm = MPI_COMM_WORLD);
/// True on every rank if `local` is true on any rank.
bool any(bool local, MPI_Comm comm = MPI_COMM_WORLD);
/// Broadcasts a string from `root`.
std::string broadcast(const std::string& value, int root = 0, MPI_Comm comm = MPI_COMM_WORLD);
/// Gathers every rank's string on all ranks, in rank order.
std::vector<std::string> all_gather(const std::string& value, MPI_Comm comm = MPI_COMM_WORLD);

}  // namespace grainwave::mpi
