#pragma once
// The subcommands of `viscd`: each registers itself on the app (main.cpp calls these).

namespace CLI {
class App;
}  // namespace CLI

namespace viscd::app {

/// Each subcommand registers itself on the app; its callback stores the exit code in `rc`.
void add_pairs_command(CLI::App& app, int& rc);
void add_run_command(CLI::App& app, int& rc);
void add_bench_command(CLI::App& app, int& rc);
void add_query_command(CLI::App& app, int& rc);
#ifdef VISCD_HAVE_VIEWER
void add_view_command(CLI::App& app, int& rc);
#endif

}  // namespace viscd::app
