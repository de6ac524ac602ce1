// The ray casts' threads, started once for the process: a certified frame
// settles a few thousand pixels in two or three parallel steps, and on a
// GPU machine's virtual cores starting 15 threads for each step took about
// as long as the step's work (H200 machine, 2026-11-27: the ring of a
// 960x540 frame 1.0-2.1 ms on 16 fresh threads).
#pragma once

#include <functional>

namespace umbra {

/// Calls task(i) for every i in [0, count), on the pool's threads (one
/// fewer than the hardware's) and the calling thread, each taking the next
/// index left; returns once every call has returned. Several threads may
/// call it at once, and a task may call it again (the caller always works
/// on its own indices, so nothing waits on a busy pool). A task must not
/// throw.
void run_on_workers(int count, const std::function<void(int)>& task);

/// The threads run_on_workers uses, the caller's included.
int worker_count();

}  // namespace umbra
