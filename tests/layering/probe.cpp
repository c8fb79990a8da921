// Layering probe: includes PROBE_HEADER with the include path of one library layer. The
// tests in CMakeLists.txt expect the build to fail for every header of a higher (or sibling)
// layer and to succeed for the layer's own dependencies.
#include PROBE_HEADER
int hpcm_layering_probe() { return 0; }
