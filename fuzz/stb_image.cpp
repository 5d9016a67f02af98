// stb_image's decoders, compiled from the system's header for fuzz builds only: the system's libstb is built
// without coverage instrumentation, so the texture fuzz target would not see inside them.
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>
