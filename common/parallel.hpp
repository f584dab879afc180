#pragma once
// How many threads the analyzer's parallel loops take (`--jobs` of the offline verbs). The loops
// are OpenMP's where the compiler has it (GCC's libgomp) and serial otherwise; each splits work
// whose parts do not touch one another (a regression's columns through a filter or a transform),
// so a result does not depend on the number of threads. The default is one thread: a library
// caller (the live estimator beside the daemon, a test under ctest -j) takes no cores it was not
// given; the offline verbs set the machine's cores unless told otherwise.
#include <functional>

namespace inertia::parallel {

/// The threads for the loops from now on; 0: the machine's cores (hardware_concurrency).
void set_jobs(int jobs);
/// The threads set (at least 1).
[[nodiscard]] int jobs();
/// The threads for a loop over `items` independent parts: no more than there are parts, and 1
/// inside a task of for_each_index (its tasks take the threads).
[[nodiscard]] int threads_for(long items);

/// Runs task(i) for every i in [0, items) on threads_for(items) threads, each thread taking the
/// next index not yet taken: whole runs (a seed's simulation and procedure) side by side. The
/// caller is one of the threads; its helpers are kept from one call to the next. Tasks
/// must not touch one another's data; results go to slots the caller sized (one per index), so
/// they do not depend on the number of threads. The loops inside a task run on its thread alone.
/// Once a task throws no new task starts, and the first exception (by index) is rethrown here
/// when every thread is done.
void for_each_index(long items, const std::function<void(long)>& task);

}  // namespace inertia::parallel
