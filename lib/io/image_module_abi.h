/* image_module_abi.h — the C interface between libivr and its image module (libivr_image), which
 * writes PNG/EXR/TIFF through OpenImageIO so that libivr itself does not link it. */
#ifndef IVR_IMAGE_MODULE_ABI_H
#define IVR_IMAGE_MODULE_ABI_H
#include <stddef.h>

/* Raised whenever the functions below change; libivr refuses a module of another version. */
#define IVR_IMAGE_MODULE_ABI 1

#ifdef __cplusplus
extern "C" {
#endif

/* The ABI version the module was built with (IVR_IMAGE_MODULE_ABI). */
typedef int (*ivr_image_module_abi_fn)(void);

/* Writes width × height pixels of `channels` interleaved values, rows from the top, as 8-bit
 * (`uint8` non-zero: unsigned char values) or as float, in the format the path's extension names.
 * Channel 4 of a float image is marked as alpha. Returns 0, or non-zero with a one-line reason in
 * `error` (NUL-terminated, at most error_size bytes). */
typedef int (*ivr_image_write_fn)(const char* path, int width, int height, int channels,
                                  int uint8, const void* pixels, char* error, size_t error_size);

#ifdef __cplusplus
}
#endif
#endif
