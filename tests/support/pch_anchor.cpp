// The one source of inertia_test_pch (cmake/InertiaTargets.cmake): the target exists to build the
// test binaries' precompiled header, which a library needs a source file to carry.
