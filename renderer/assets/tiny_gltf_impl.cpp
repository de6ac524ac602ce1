// tinygltf's implementation, compiled exactly once. The options (no image
// decoding, no external images, no built-in file system: LoadOptions'
// callbacks are the only way to a file) are compile definitions of the
// umbra_models target, so every file that includes tiny_gltf.h sees the
// same declarations.
// tiny_gltf.h 2.7 uses std::ofstream (its writer) without including
// <fstream> when TINYGLTF_NO_FS is set.
#include <fstream>

#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
