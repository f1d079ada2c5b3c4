#include "core/Mpi.hpp"

#include <algorithm>

namespace grainwave::mpi {

Session::Session(int* argc, char*** argv) {
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised) {
    MPI_Init(argc, argv);
    owns_ = true;
  }
}

Session::~Session() {
  int finalised = 0;
  MPI_Finalized(&finalised);
  if (owns_ && !finalised) MPI_Finalize();
}

int rank(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}

int size(MPI_Comm comm) {
  int s = 1;
  MPI_Comm_size(comm, &s);
  return s;
}

namespace {
template <class T>
T all_reduce(T local, MPI_Datatype type, MPI_Op op, MPI_Comm comm) {
  T result{};
  MPI_Allreduce(&local, &result, 1, type, op, comm);
  return result;
}
}  // namespace

double sum(double local, MPI_Comm comm) { return all_reduce(local, MPI_DOUBLE, MPI_SUM, comm); }
double max(double local, MPI_Comm comm) { return all_reduce(local, MPI_DOUBLE, MPI_MAX, comm); }
double min(double local, MPI_Comm comm) { return all_reduce(local, MPI_DOUBLE, MPI_MIN, comm); }
std::int64_t sum(std::int64_t local, MPI_Comm comm) {
  return all_reduce(local, MPI_INT64_T, MPI_SUM, comm);
}
std::int64_t max(std::int64_t local, MPI_Comm comm) {
  return all_reduce(local, MPI_INT64_T, MPI_MAX, comm);
}

std::int64_t exclusive_prefix_sum(std::int64_t local, MPI_Comm comm) {
  std::int64_t before = 0;
  MPI_Exscan(&local, &before, 1, MPI_INT64_T, MPI_SUM, comm);
  return rank(comm) == 0 ? 0 : before;
}

bool any(bool local, MPI_Comm comm) {
  return all_reduce(local ? 1 : 0, MPI_INT, MPI_MAX, comm) != 0;
}

std::string broadcast(const std::string& value, int root, MPI_Comm comm) {
  std::int64_t n = static_cast<std::int64_t>(value.size());
  MPI_Bcast(&n, 1, MPI_INT64_T, root, comm);
  std::string result = rank(comm) == root ? value : std::string(static_cast<std::size_t>(n), '\0');
  if (n > 0) MPI_Bcast(result.data(), static_cast<int>(n), MPI_CHAR, root, comm);
  return result;
}

namespace {
/// Every rank's count of `n`, and where each rank's part starts in the concatenation.
struct GatherLayout {
  std::vector<int> counts, offsets;
  int total = 0;
};
GatherLayout gather_layout(int n, MPI_Comm comm) {
  const auto p = static_cast<std::size_t>(size(comm));
  GatherLayout layout{std::vector<int>(p), std::vector<int>(p), 0};
  MPI_Allgather(&n, 1, MPI_INT, layout.counts.data(), 1, MPI_INT, comm);
  for (std::size_t i = 0; i < p; ++i) {
    layout.offsets[i] = layout.total;
    layout.total += layout.counts[i];
  }
  return layout;
}
}  // namespace

std::vector<std::string> all_gather(const std::string& value, MPI_Comm comm) {
  const int p = size(comm);
  const int n = static_cast<int>(value.size());
  const auto [counts, offsets, total] = gather_layout(n, comm);
  std::string all(static_cast<std::size_t>(total), '\0');
  MPI_Allgatherv(value.data(), n, MPI_CHAR, all.data(), counts.data(), offsets.data(), MPI_CHAR,
                 comm);
  std::vector<std::string> out;
  for (int i = 0; i < p; ++i)
    out.push_back(all.substr(static_cast<std::size_t>(offsets[static_cast<std::size_t>(i)]),
                             static_cast<std::size_t>(counts[static_cast<std::size_t>(i)])));
  return out;
}

std::vector<double> all_gather(const std::vector<double>& values, MPI_Comm comm) {
  const int n = static_cast<int>(values.size());
  const auto [counts, offsets, total] = gather_layout(n, comm);
  std::vector<double> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(values.data(), n, MPI_DOUBLE, all.data(), counts.data(), offsets.data(),
                 MPI_DOUBLE, comm);
  return all;
}

void sum_in_place(std::vector<double>& values, MPI_Comm comm) {
  if (size(comm) == 1 || values.empty()) return;
  MPI_Allreduce(MPI_IN_PLACE, values.data(), static_cast<int>(values.size()), MPI_DOUBLE,
                MPI_SUM, comm);
}

Exchange::Exchange(MPI_Comm comm) : comm_(comm) {
  const auto p = static_cast<std::size_t>(size(comm));
  outgoing_.resize(p);
  send_counts_.resize(p);
  send_offsets_.resize(p);
  receive_counts_.resize(p);
  receive_offsets_.resize(p);
}

void Exchange::clear() {
  for (auto& buffer : outgoing_) buffer.clear();
}

void Exchange::exchange() {
  const std::size_t p = outgoing_.size();
  int total = 0;
  for (std::size_t r = 0; r < p; ++r) {
    send_counts_[r] = static_cast<int>(outgoing_[r].size());
    send_offsets_[r] = total;
    total += send_counts_[r];
  }
  send_.resize(static_cast<std::size_t>(total));
  for (std::size_t r = 0; r < p; ++r)
    std::copy(outgoing_[r].begin(), outgoing_[r].end(),
              send_.begin() + send_offsets_[r]);
  MPI_Alltoall(send_counts_.data(), 1, MPI_INT, receive_counts_.data(), 1, MPI_INT, comm_);
  int received = 0;
  for (std::size_t r = 0; r < p; ++r) {
    receive_offsets_[r] = received;
    received += receive_counts_[r];
  }
  incoming_.resize(static_cast<std::size_t>(received));
  MPI_Alltoallv(send_.data(), send_counts_.data(), send_offsets_.data(), MPI_DOUBLE,
                incoming_.data(), receive_counts_.data(), receive_offsets_.data(), MPI_DOUBLE,
                comm_);
}

}  // namespace grainwave::mpi
