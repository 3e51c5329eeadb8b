// Uses the installed viscd::mpi: two spheres per rank in a row along x, each touching the next
// (rank r holds ids 2r and 2r + 1), so K ranks give 2K - 1 pairs, K - 1 of them across ranks.
#include <viscd/mpi.hpp>

#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  int rc = 0;
  {
    viscd::mpi::DistributedDetector det(MPI_COMM_WORLD);
    const auto x = static_cast<float>(4 * rank);
    const std::vector<viscd::Sphere> spheres{{x, 0, 0, 1}, {x + 2, 0, 0, 1}};
    const std::vector<std::uint64_t> ids{2ull * rank, 2ull * rank + 1};
    viscd::mpi::DistributedInput in;
    in.spheres = spheres;
    in.ids = ids;
    viscd::mpi::DistributedResult out;
    std::vector<viscd::mpi::GlobalPair> all;
    if (viscd::Status s = det.detect(in, out); !s) {
      std::fprintf(stderr, "mpi_consumer: %s\n", s.error().c_str());
      rc = 1;
    } else if (viscd::Status g = det.gather_pairs(out, all); !g) {
      rc = 1;
    } else if (rank == 0) {
      bool chain = all.size() == static_cast<std::size_t>(2 * size - 1);
      for (std::size_t k = 0; chain && k < all.size(); ++k) chain = all[k].a == k && all[k].b == k + 1;
      std::printf("mpi_consumer: %d ranks, %zu pairs%s\n", size, all.size(), chain ? ", a chain" : ", WRONG");
      rc = chain ? 0 : 1;
    }
  }
  MPI_Finalize();
  return rc;
}
