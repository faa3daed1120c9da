// The C interface between the image codec loader (image_codec.cpp) and the
// OpenImageIO module (image_codec_oiio.cpp): plain C types, no exception
// crosses it. Each function returns 0 on success, else writes a message
// (NUL-terminated, truncated to err_size) and returns nonzero. Buffers the
// module allocates are freed with ropsim_oiio_free.
#pragma once
#include <stddef.h>

extern "C" {

/// Bumped on any change below; the loader refuses a module of another version.
#define ROPSIM_OIIO_ABI_VERSION 3

int ropsim_oiio_abi_version(void);

/// Decodes a file (data == NULL) or a memory buffer (data, bytes; path then
/// names the format by its extension). *px receives width * height * channels
/// floats, unassociated alpha. color_space receives the file's colour space
/// as OpenImageIO names it ("oiio:ColorSpace"; empty if it names none,
/// truncated to cs_size), *is_float whether its pixels are stored as floats.
int ropsim_oiio_decode(const char* path, const void* data, size_t bytes, int* width, int* height, int* channels,
                       float** px, char* color_space, size_t cs_size, int* is_float, char* err, size_t err_size);

/// Fills row y of an image being encoded: width * 3 values (exr: float; png:
/// unsigned char). Must not throw.
typedef void (*ropsim_oiio_row_fn)(void* ctx, int y, void* row);

/// Encodes width x height RGB pixels, asked for row by row from the top (so
/// only one row is held uncompressed), in the format of path's extension into
/// *out (*out_bytes bytes).
int ropsim_oiio_encode(const char* path, int width, int height, ropsim_oiio_row_fn rows, void* ctx, unsigned char** out,
                       size_t* out_bytes, char* err, size_t err_size);

void ropsim_oiio_free(void* p);
}
