#include "cluster/cluster.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

#ifdef PX_HAVE_MPI
#include <mpi.h>
#endif

namespace px {

namespace {

using clock_type = std::chrono::steady_clock;

// Started by an MPI launcher? (Open MPI, MPICH / Hydra, PMIx, Slurm's PMI.) Outside one,
// parallax never initialises MPI: a plain run must not depend on an MPI runtime.
bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"})
    if (std::getenv(v)) return true;
  return false;
}

#ifdef PX_HAVE_MPI
void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw std::runtime_error(std::string("MPI ") + what + ": " + std::string(text, len));
}

// MPI counts are ints: larger messages go in chunks (never needed below 2 GB strips).
constexpr std::size_t kChunk = static_cast<std::size_t>(std::numeric_limits<int>::max());
#endif

struct Timer {
  double& total;
  clock_type::time_point t0 = clock_type::now();
  ~Timer() { total += std::chrono::duration<double, std::milli>(clock_type::now() - t0).count(); }
};

}  // namespace

bool Cluster::mpi_built() {
#ifdef PX_HAVE_MPI
  return true;
#else
  return false;
#endif
}

Cluster& Cluster::world() {
  static Cluster cluster;
  return cluster;
}

Cluster::Cluster() {
#ifdef PX_HAVE_MPI
  if (launched_by_mpi()) {
    int provided = 0;
    check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "init");
    // Errors come back as codes (and become exceptions here) instead of killing the job
    // without a message.
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    mpi_ = true;
  }
#else
  if (launched_by_mpi() && std::getenv("OMPI_COMM_WORLD_SIZE") && std::atoi(std::getenv("OMPI_COMM_WORLD_SIZE")) > 1)
    std::fprintf(stderr,
                 "warning: started by mpirun, but this parallax was built without MPI: every rank renders "
                 "the whole frame alone (install libopenmpi-dev and rebuild)\n");
#endif
  bytes_sent_.assign(size_, 0);
}

Cluster::~Cluster() {
#ifdef PX_HAVE_MPI
  if (mpi_) {
    try {
      wait_sends();
    } catch (...) {}
    MPI_Finalize();
  }
#endif
}

void Cluster::send(int to, const void* data, std::size_t bytes) {
  if (to == rank_ || to < 0 || to >= size_) throw std::logic_error("Cluster::send: bad destination rank");
#ifdef PX_HAVE_MPI
  Timer t{mpi_ms_};
  const char* p = static_cast<const char*>(data);
  do {
    const std::size_t n = std::min(bytes, kChunk);
    auto* req = new MPI_Request;
    check(MPI_Isend(p, static_cast<int>(n), MPI_BYTE, to, 0, MPI_COMM_WORLD, req), "send");
    pending_.push_back(req);
    p += n;
    bytes -= n;
    bytes_sent_[to] += n;
  } while (bytes > 0);
#else
  (void)data;
  (void)bytes;
#endif
}

void Cluster::recv(int from, void* data, std::size_t bytes) {
  if (from == rank_ || from < 0 || from >= size_) throw std::logic_error("Cluster::recv: bad source rank");
#ifdef PX_HAVE_MPI
  Timer t{mpi_ms_};
  char* p = static_cast<char*>(data);
  do {
    const std::size_t n = std::min(bytes, kChunk);
    MPI_Status status;
    check(MPI_Recv(p, static_cast<int>(n), MPI_BYTE, from, 0, MPI_COMM_WORLD, &status), "receive");
    int got = 0;
    MPI_Get_count(&status, MPI_BYTE, &got);
    if (static_cast<std::size_t>(got) != n)
      throw std::runtime_error("MPI receive from rank " + std::to_string(from) + ": expected " + std::to_string(n) +
                               " bytes, got " + std::to_string(got) + " (ranks disagree on the schedule)");
    p += n;
    bytes -= n;
  } while (bytes > 0);
#else
  (void)data;
  (void)bytes;
#endif
}

void Cluster::wait_sends() {
#ifdef PX_HAVE_MPI
  Timer t{mpi_ms_};
  for (void* r : pending_) {
    auto* req = static_cast<MPI_Request*>(r);
    const int rc = MPI_Wait(req, MPI_STATUS_IGNORE);
    delete req;
    if (rc != MPI_SUCCESS) {
      pending_.clear();
      check(rc, "send completion");
    }
  }
#endif
  pending_.clear();
}

void Cluster::broadcast(void* data, std::size_t bytes) {
#ifdef PX_HAVE_MPI
  if (!mpi_) return;
  Timer t{mpi_ms_};
  check(MPI_Bcast(data, static_cast<int>(bytes), MPI_BYTE, 0, MPI_COMM_WORLD), "broadcast");
#else
  (void)data;
  (void)bytes;
#endif
}

std::uint64_t Cluster::sum(std::uint64_t value) {
#ifdef PX_HAVE_MPI
  if (!mpi_) return value;
  Timer t{mpi_ms_};
  std::uint64_t total = 0;
  check(MPI_Allreduce(&value, &total, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD), "sum");
  return total;
#else
  return value;
#endif
}

std::vector<double> Cluster::gather(const std::vector<double>& mine) {
#ifdef PX_HAVE_MPI
  if (!mpi_) return mine;
  Timer t{mpi_ms_};
  int n = static_cast<int>(mine.size());
  std::vector<int> counts(size_), offsets(size_);
  check(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "gather");
  std::vector<double> all;
  if (rank_ == 0) {
    int total = 0;
    for (int r = 0; r < size_; ++r) {
      offsets[r] = total;
      total += counts[r];
    }
    all.resize(total);
  }
  check(
      MPI_Gatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE, 0, MPI_COMM_WORLD),
      "gather");
  return all;
#else
  return mine;
#endif
}

std::vector<std::string> Cluster::failures(bool ok, const std::string& why) {
  std::vector<std::string> out;
  if (!mpi_) {
    if (!ok) out.push_back(why);
    return out;
  }
#ifdef PX_HAVE_MPI
  // Message lengths first, then the messages (empty for ranks that worked).
  const std::string mine = ok ? std::string() : why.empty() ? std::string("failed") : why;
  int len = static_cast<int>(mine.size());
  std::vector<int> lens(size_), offsets(size_);
  check(MPI_Allgather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, MPI_COMM_WORLD), "allgather");
  int total = 0;
  for (int r = 0; r < size_; ++r) {
    offsets[r] = total;
    total += lens[r];
  }
  std::string all(static_cast<std::size_t>(total), '\0');
  check(MPI_Allgatherv(mine.data(), len, MPI_CHAR, all.data(), lens.data(), offsets.data(), MPI_CHAR, MPI_COMM_WORLD),
        "allgather");
  for (int r = 0; r < size_; ++r)
    if (lens[r] > 0) out.push_back("rank " + std::to_string(r) + ": " + all.substr(offsets[r], lens[r]));
#endif
  return out;
}

void Cluster::abort(int code) {
  std::fflush(stdout);
  std::fflush(stderr);
#ifdef PX_HAVE_MPI
  if (mpi_) MPI_Abort(MPI_COMM_WORLD, code);
#endif
  std::exit(code);
}

void Cluster::reset_traffic() {
  bytes_sent_.assign(size_, 0);
  mpi_ms_ = 0.0;
}

}  // namespace px
