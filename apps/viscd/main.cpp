// viscd: visibility-based collision detection for very many moving spheres.
#include <CLI/CLI.hpp>
#include <exception>
#include <new>
#include <string>
#include <string_view>
#include <vector>

#include "commands.hpp"
#include "exit_codes.hpp"
#include "mpi_session.hpp"
#include "viscd/io.hpp"
#include "viscd/version.hpp"

int main(int argc, char** argv) {
  // Under mpirun: MPI for the whole run, rank 0 speaks (docs/mpi.md). Only `pairs` spreads over
  // ranks; any other command would run K copies of itself.
  viscd::app::MpiSession mpi(argc, argv);
  const int ranks = viscd::app::MpiSession::active() ? viscd::app::MpiSession::size() : viscd::app::launched_ranks();
  if (ranks > 1) {
    const bool pairs = argc > 1 && std::string_view(argv[1]) == "pairs";
    if (!viscd::app::MpiSession::active()) {
      std::fprintf(stderr,
                   "viscd: error: started as %d MPI ranks, but this viscd was built without MPI "
                   "(install libopenmpi-dev and rebuild; docs/mpi.md)\n",
                   ranks);
      return viscd::app::kExitUsage;
    }
    if (!pairs) {
      std::fprintf(stderr,
                   "viscd: error: under mpirun only `viscd pairs` spreads over the ranks (%d here); run "
                   "other commands as one process\n",
                   ranks);
      return viscd::app::kExitUsage;
    }
  }
  CLI::App app{
      "viscd finds every colliding pair among very many moving spheres (or boxes) each frame, and skips the\n"
      "objects the viewer cannot meaningfully see (Sung, IEEE Access 2023): objects covering fewer\n"
      "than lambda pixels of the visibility map are culled, the rest go through an exact LBVH\n"
      "broadphase whose Morton code width (16/32/64 bits) follows the mean pixel count.",
      "viscd"};
  app.footer(
      "\nExamples:\n"
      "  viscd run                                  # the demo: 10 000 objects, 1280x720, zoom-out\n"
      "  viscd run --objects 100000 --no-culling    # everything active\n"
      "  viscd run --camera zoom-in --frames 60 --screenshot near.png\n"
      "  viscd pairs --spheres scene.xyzr --out pairs.csv --stats stats.json\n"
      "  viscd pairs --spheres scene.csv --camera cam.json --lambda 50\n"
      "  viscd pairs --spheres scene.csv --id-map ids.u32 --map-size 1280x720   # your own visibility map\n"
      "  viscd pairs --boxes crates.csv --static walls.csv    # boxes, and a static set (numbered N + k)\n"
      "  viscd query --spheres scene.csv --ray 0,0,-50,0,0,1 --all      # the spheres a ray hits\n"
      "  viscd run --shape box --static 300         # the demo as boxes, on a field of rocks and pillars\n"
      "  viscd run --events events.csv --pairs-dir pairs/              # contact events, every frame's pairs\n"
      "  viscd bench paper --sizes 1000,10000,100000   # the paper's tables and figures\n"
      "  viscd view                                 # the same in a window (xvfb-run without a display)\n"
      "\nExit codes: 0 success, 1 bad input or a failed run, 2 bad usage (unknown option, bad value),\n"
      "3 a --validate-hash mismatch.\n"
      "\nRun `viscd <command> --help` for a command's options. Docs: docs/usage.md");
  app.require_subcommand(1);
  app.set_version_flag("--version", std::to_string(viscd::kVersionMajor) + "." + std::to_string(viscd::kVersionMinor) +
                                        "." + std::to_string(viscd::kVersionPatch));
  int rc = 0;
  viscd::app::add_run_command(app, rc);
  viscd::app::add_pairs_command(app, rc);
  viscd::app::add_query_command(app, rc);
  viscd::app::add_bench_command(app, rc);
#ifdef VISCD_HAVE_VIEWER
  viscd::app::add_view_command(app, rc);
#endif
  // CLI11 gives each command the tool's footer; a command shows its own examples, or points back.
  const std::string tool_footer = app.get_footer();
  auto own_footers = [&](auto& self, CLI::App& parent) -> void {
    for (CLI::App* sub : parent.get_subcommands([](CLI::App*) { return true; })) {
      if (sub->get_footer() == tool_footer)
        sub->footer("\n`viscd --help` shows examples of every command. Docs: docs/usage.md");
      self(self, *sub);
    }
  };
  own_footers(own_footers, app);
  // `viscd bench peers -- ARGS`: CLI11 would hand everything after `--` to the top-level app as
  // positionals; the `--` only marks where the driver's arguments begin, so drop it here.
  std::vector<char*> args(argv, argv + argc);
  if (args.size() > 3 && std::string_view(args[1]) == "bench" && std::string_view(args[2]) == "peers" &&
      std::string_view(args[3]) == "--")
    args.erase(args.begin() + 3);
  try {
    app.parse(static_cast<int>(args.size()), args.data());
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    // CLI11's messages quote the offending argument: print it escaped and cut.
    std::fprintf(stderr, "viscd: error: %s\nRun with --help for more information.\n",
                 viscd::printable(e.what(), 300).c_str());
    return viscd::app::kExitUsage;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "viscd: error: out of memory (fewer objects, a smaller --map-size or a lower "
                 "--max-pair-memory need less)\n");
    return viscd::app::kExitFailed;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "viscd: error: %s\n", viscd::printable(e.what(), 300).c_str());
    return viscd::app::kExitFailed;
  }
  return rc;
}
