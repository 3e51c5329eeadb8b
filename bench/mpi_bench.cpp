// viscd_mpi_bench: the distributed detector's scaling (docs/mpi.md, "Measured"). Run under
// mpirun; rank 0 prints one CSV row per configuration and, with --csv, appends them to a file.
//
//   strong  --objects N in all, split over the K ranks of the run
//   weak    --objects N per rank: the world grows with K, its density stays
//
// The world: spheres of radius 0.5 uniform in a box of density 0.2 per unit volume (about 0.4
// pairs per object), cut into K slabs along x, rank r owning slab r. Every frame moves every
// object by a small random step that keeps it in its slab, so each frame rebuilds. Each row holds
// medians over frames of the slowest rank's whole call, its exchange (checks, region, ghost
// selection and the MPI calls), those MPI calls alone (communication) and its local frame, the
// ghosts a rank receives per own object (halo share, mean over ranks) and the bytes a rank sends
// (mean). With one rank the plain cpu detector runs the same frames, interleaved, for the
// overhead of the distributed call.
#include <mpi.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "viscd/mpi.hpp"
#include "viscd/viscd.hpp"

namespace viscd::bench {
namespace {

struct Options {
  std::string mode = "strong";
  std::vector<std::uint64_t> objects{1000000};
  int frames = 10, warmup = 2, threads = 0;
  std::string csv;
};

double max_over_ranks(double v) {
  double m = 0;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return m;
}
double mean_over_ranks(double v) {
  double s = 0;
  MPI_Allreduce(&v, &s, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  int k = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &k);
  return s / k;
}

int run(const Options& o) {
  int rank = 0, k = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &k);
  if (rank == 0)
    std::printf(
        "mode,ranks,objects,objects_per_rank,frame_ms,exchange_ms,communication_ms,detect_ms,halo_share,"
        "bytes_sent_per_rank,plain_ms,pairs\n");
  for (const std::uint64_t n_arg : o.objects) {
    const std::uint64_t total = o.mode == "weak" ? n_arg * static_cast<std::uint64_t>(k) : n_arg;
    const std::uint64_t first = total * static_cast<std::uint64_t>(rank) / static_cast<std::uint64_t>(k);
    const std::uint64_t mine = total * (static_cast<std::uint64_t>(rank) + 1) / static_cast<std::uint64_t>(k) - first;
    // A box of volume total / 0.2: x spans the slabs, y and z are shared.
    const double side = std::cbrt(static_cast<double>(total) / 0.2);
    const auto slab = static_cast<float>(side / k), lo = static_cast<float>(rank) * slab, hi = lo + slab;
    const auto s = static_cast<float>(side);
    std::mt19937_64 rng(1234 + static_cast<std::uint64_t>(rank));
    std::uniform_real_distribution<float> ux(lo, hi), uyz(0, s), step(-0.05f, 0.05f);
    std::vector<Sphere> spheres(mine);
    std::vector<std::uint64_t> ids(mine);
    for (std::uint64_t i = 0; i < mine; ++i) {
      spheres[i] = {ux(rng), uyz(rng), uyz(rng), 0.5f};
      ids[i] = first + i;
    }
    Config config = bench_config();
    config.threads = o.threads;
    mpi::DistributedDetector det(MPI_COMM_WORLD, config);
    auto plain = make_cpu_detector(config);
    mpi::DistributedInput in;
    in.spheres = spheres;
    in.ids = ids;
    mpi::DistributedResult out;
    FrameResult plain_out;
    std::vector<double> frame, exchange, comm, detect, plain_ms, halo, bytes;
    std::uint64_t pairs = 0;
    for (int f = 0; f < o.warmup + o.frames; ++f) {
      for (auto& sp : spheres) {
        sp.x = std::clamp(sp.x + step(rng), lo, std::nextafter(hi, lo));
        sp.y = std::clamp(sp.y + step(rng), 0.0f, s);
        sp.z = std::clamp(sp.z + step(rng), 0.0f, s);
      }
      MPI_Barrier(MPI_COMM_WORLD);
      if (Status st = det.detect(in, out); !st) {
        if (rank == 0) std::fprintf(stderr, "viscd_mpi_bench: %s\n", st.error().c_str());
        return 1;
      }
      double p = 0;
      if (k == 1) {  // the plain detector on the same frame, right after
        const auto t0 = Clock::now();
        if (Status st = plain->detect(spheres, nullptr, plain_out); !st) return 1;
        p = ms_since(t0);
      }
      const double t = max_over_ranks(out.stats.total_ms), e = max_over_ranks(out.stats.exchange_ms),
                   d = max_over_ranks(out.stats.detect_ms), c = max_over_ranks(out.stats.communication_ms);
      const double h =
          mean_over_ranks(mine > 0 ? static_cast<double>(out.stats.ghosts_received) / static_cast<double>(mine) : 0);
      const double b = mean_over_ranks(static_cast<double>(out.stats.bytes_sent));
      std::uint64_t mp = out.pairs.size();
      MPI_Allreduce(&mp, &pairs, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
      if (f < o.warmup) continue;
      frame.push_back(t), exchange.push_back(e), comm.push_back(c), detect.push_back(d), halo.push_back(h),
          bytes.push_back(b);
      plain_ms.push_back(p);
    }
    if (rank == 0) {
      char row[512];
      std::snprintf(row, sizeof row, "%s,%d,%llu,%llu,%.3f,%.3f,%.3f,%.3f,%.4f,%.0f,%.3f,%llu\n", o.mode.c_str(), k,
                    static_cast<unsigned long long>(total), static_cast<unsigned long long>(total / k), median(frame),
                    median(exchange), median(comm), median(detect), median(halo), median(bytes),
                    k == 1 ? median(plain_ms) : 0.0, static_cast<unsigned long long>(pairs));
      std::fputs(row, stdout);
      std::fflush(stdout);
      if (!o.csv.empty())
        if (FILE* f = std::fopen(o.csv.c_str(), "a")) {
          std::fputs(row, f);
          std::fclose(f);
        }
    }
  }
  return 0;
}

}  // namespace
}  // namespace viscd::bench

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  viscd::bench::Options o;
  CLI::App app{"viscd_mpi_bench: the distributed detector's strong and weak scaling (docs/mpi.md). Run under mpirun."};
  app.add_option("--mode", o.mode, "strong: --objects in all; weak: --objects per rank")
      ->check(CLI::IsMember({"strong", "weak"}))
      ->capture_default_str();
  app.add_option("--objects", o.objects, "object counts, comma-separated")->delimiter(',');
  app.add_option("--frames", o.frames, "timed frames per row")->capture_default_str();
  app.add_option("--warmup", o.warmup, "untimed frames first")->capture_default_str();
  app.add_option("--threads", o.threads, "threads per rank (0: all cores)")->capture_default_str();
  app.add_option("--csv", o.csv, "append the rows to this file (rank 0)");
  int rc = 0;
  try {
    app.parse(argc, argv);
    rc = viscd::bench::run(o);
  } catch (const CLI::ParseError& e) {
    rc = app.exit(e);
  }
  MPI_Finalize();
  return rc;
}
