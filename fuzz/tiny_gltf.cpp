// tinygltf's implementation, compiled from the system's header for fuzz builds only: the system's libtinygltf is a
// shared library built without coverage instrumentation, so the glTF fuzz target would not see inside it. Built
// without stb_image (TINYGLTF_NO_STB_IMAGE, set for every file that includes the header): the reader decodes
// images itself.
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
