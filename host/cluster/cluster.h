// The processes one frame is split across: the ranks of an MPI job when parallax runs under
// `mpirun -np R`, otherwise a cluster of one process. Each rank drives its own local devices;
// the frame's devices are numbered rank by rank (rank r holds global devices r*N .. r*N+N-1),
// and strips go to global devices in order, so neighbouring strips share a rank wherever they
// can and only the strips at rank borders exchange halo rows over the network.
//
// Messages: the pipeline sends strips and halo rows as byte ranges, point to point. Every rank
// walks the same schedule in the same order, and MPI keeps the order of messages between two
// ranks, so a receive always matches the send the schedule meant; sends are non-blocking
// (their bytes must stay alive until wait_sends()) and a receive blocks only its own host
// thread. Without MPI support compiled in, or outside mpirun, there is one rank and no
// message is ever sent.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace px {

class Cluster {
 public:
  // The process's cluster. The first call joins the MPI job if the process was started by an
  // MPI launcher (and MPI support is built in); later calls return the same object.
  static Cluster& world();
  // Whether this build can run across MPI ranks.
  static bool mpi_built();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool distributed() const { return size_ > 1; }

  // Point to point. send() copies nothing: `data` must stay valid until wait_sends().
  void send(int to, const void* data, std::size_t bytes);
  void recv(int from, void* data, std::size_t bytes);
  void wait_sends();

  // Collective: every rank must call them in the same order.
  void broadcast(void* data, std::size_t bytes);  // from rank 0
  std::uint64_t sum(std::uint64_t value);         // over all ranks
  // Rank 0 gets every rank's values concatenated in rank order; the others get an empty vector.
  std::vector<double> gather(const std::vector<double>& mine);
  // Every rank says whether its step worked (and why not); returns each failing rank's message
  // ("rank R: why"), the same on every rank. Empty: all worked.
  std::vector<std::string> failures(bool ok, const std::string& why);

  // Ends every rank of the job now (after a rank failed mid-frame, when the others would
  // otherwise wait for it forever).
  [[noreturn]] void abort(int code);
  // Says that every rank agreed to stop (a failure all ranks know about), so a failing exit
  // code needs no abort.
  void mark_orderly_exit() { orderly_exit_ = true; }
  bool orderly_exit() const { return orderly_exit_; }

  // Traffic since the last reset: bytes this rank sent to each rank, and host time spent in
  // MPI calls (ms).
  const std::vector<std::uint64_t>& bytes_sent_to() const { return bytes_sent_; }
  double mpi_ms() const { return mpi_ms_; }
  void reset_traffic();

  ~Cluster();
  Cluster(const Cluster&) = delete;
  Cluster& operator=(const Cluster&) = delete;

 private:
  Cluster();

  int rank_ = 0, size_ = 1;
  bool mpi_ = false;
  bool orderly_exit_ = false;
  std::vector<void*> pending_;  // MPI_Request handles of sends in flight
  std::vector<std::uint64_t> bytes_sent_;
  double mpi_ms_ = 0.0;
};

// Which rank holds global device `g` when every rank drives `per_rank` devices.
struct DeviceLayout {
  int rank = 0, ranks = 1, per_rank = 1;
  int count() const { return ranks * per_rank; }
  int first_local() const { return rank * per_rank; }
  bool is_local(int g) const { return g >= first_local() && g < first_local() + per_rank; }
  int local_index(int g) const { return g - first_local(); }
  int rank_of(int g) const { return g / per_rank; }
};

}  // namespace px
