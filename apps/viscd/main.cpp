// viscd: visibility-based collision detection for very many moving spheres.
#include <CLI/CLI.hpp>

#include "common.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "viscd finds every colliding pair among very many moving spheres each frame, and skips the\n"
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
      "  viscd bench paper --sizes 1000,10000,100000   # the paper's tables and figures\n"
      "  viscd view                                 # the same in a window (xvfb-run without a display)\n"
      "\nRun `viscd <command> --help` for a command's options. Docs: docs/usage.md");
  app.require_subcommand(1);
  app.set_version_flag("--version", std::to_string(viscd::kVersionMajor) + "." + std::to_string(viscd::kVersionMinor) +
                                        "." + std::to_string(viscd::kVersionPatch));
  int rc = 0;
  viscd::app::add_run_command(app, rc);
  viscd::app::add_pairs_command(app, rc);
  viscd::app::add_bench_command(app, rc);
#ifdef VISCD_HAVE_VIEWER
  viscd::app::add_view_command(app, rc);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return rc;
}
