// umbra-bench --speed: Umbra's frame time and accuracy against the plain
// frame (bench/plain_frame.hpp), in the same run (see speed_bench.cpp).
#pragma once

namespace umbra::bench {

/// Runs the speed mode with umbra-bench's command line (which holds
/// "--speed"); returns the process exit status. Throws std::runtime_error
/// for a bad option or a failed render.
int run_speed(int argc, char** argv);

}  // namespace umbra::bench
