#pragma once
// viscd under mpirun: MPI is started when an MPI launcher started the process, and only rank 0
// speaks (every other rank's output goes to /dev/null; failures reach rank 0 through agree()).
namespace viscd::app {

/// Whether an MPI launcher (mpirun, mpiexec, srun) started this process: one of Open MPI's
/// OMPI_COMM_WORLD_SIZE, PMIx's PMIX_RANK or PMI's PMI_SIZE is set.
[[nodiscard]] bool launched_by_mpi();

/// MPI for the process's lifetime: initialized in the constructor when launched_by_mpi() and
/// this viscd was built with MPI, finalized in the destructor. One per process (main()).
class MpiSession {
 public:
  MpiSession(int& argc, char**& argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  /// Whether MPI was initialized; rank() and size() are 0 and 1 otherwise.
  [[nodiscard]] static bool active();
  [[nodiscard]] static int rank();
  [[nodiscard]] static int size();
};

/// The ranks an MPI launcher started, from its environment (1 when none did or it does not say):
/// for a viscd built without MPI, to refuse running K copies of one job.
[[nodiscard]] int launched_ranks();

}  // namespace viscd::app
