// tinyobjloader's parser, compiled from the system's header for fuzz builds only: the system's library is built
// without coverage instrumentation, so the OBJ fuzz target would not see inside it. TINYOBJLOADER_USE_DOUBLE comes
// from the build, as for the system's double variant that other builds link.
#define TINYOBJLOADER_IMPLEMENTATION
#include <tiny_obj_loader.h>
