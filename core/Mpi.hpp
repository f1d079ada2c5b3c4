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
/// Gathers every rank's values on all ranks, concatenated in rank order.
std::vector<double> all_gather(const std::vector<double>& values, MPI_Comm comm = MPI_COMM_WORLD);
/// Element-wise sum over ranks, in place (every rank passes the same length).
void sum_in_place(std::vector<double>& values, MPI_Comm comm = MPI_COMM_WORLD);

/// Personalised all-to-all exchange of doubles with reusable buffers: each rank fills
/// outgoing(r) for every destination r (its own included, usually empty), then exchange()
/// delivers them; incoming() holds what the ranks sent to this one, concatenated in rank order.
/// Nothing is allocated once the buffers have reached their working size.
class Exchange {
 public:
  explicit Exchange(MPI_Comm comm = MPI_COMM_WORLD);
  /// Empties every outgoing buffer (their capacity is kept).
  void clear();
  std::vector<double>& outgoing(int destination) { return outgoing_[static_cast<std::size_t>(destination)]; }
  /// Collective: sends the outgoing buffers and receives the incoming ones.
  void exchange();
  const std::vector<double>& incoming() const { return incoming_; }

 private:
  MPI_Comm comm_;
  std::vector<std::vector<double>> outgoing_;
  std::vector<double> send_, incoming_;
  std::vector<int> send_counts_, send_offsets_, receive_counts_, receive_offsets_;
};

}  // namespace grainwave::mpi
