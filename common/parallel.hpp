#pragma once
// How many threads the analyzer's parallel loops take (`--jobs` of the offline verbs). The loops
// are OpenMP's where the compiler has it (GCC's libgomp) and serial otherwise; each splits work
// whose parts do not touch one another (a regression's columns through a filter or a transform),
// so a result does not depend on the number of threads. The default is one thread: a library
// caller (the live estimator beside the daemon, a test under ctest -j) takes no cores it was not
// given; the offline verbs set the machine's cores unless told otherwise.
namespace inertia::parallel {

/// The threads for the loops from now on; 0: the machine's cores (hardware_concurrency).
void set_jobs(int jobs);
/// The threads set (at least 1).
[[nodiscard]] int jobs();
/// The threads for a loop over `items` independent parts: no more than there are parts.
[[nodiscard]] int threads_for(long items);

}  // namespace inertia::parallel
