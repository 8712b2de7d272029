/* model_png.h - the PNG images of a model's views (model.h): 16-bit RGBA weight images and
 * 8-bit mono masks, with libspng; 8-bit RGB for the glTF textures (export_gltf.c). Private
 * to appearance/. */
#pragma once

#include <stddef.h>
#include <stdint.h>

/* Encodes width x height pixels of `channels` samples (4: RGBA 16-bit from u16; 3: RGB 8-bit
 * and 1: mono 8-bit from u8, u16 NULL) as PNG into a malloc'ed *buf of *len bytes. Returns 0,
 * -ENOMEM or -EIO. */
int ap_png_encode(int width, int height, int channels, const uint16_t *u16, const uint8_t *u8,
                  void **buf, size_t *len);

/* Decodes a PNG of exactly width x height into out (RGBA 16-bit into u16, 4 samples a pixel,
 * or mono 8-bit into u8). Returns 0, -EBADMSG (not a PNG, or another size or colour type:
 * why in err) or -ENOMEM. */
int ap_png_decode(const void *buf, size_t len, int width, int height, uint16_t *u16, uint8_t *u8,
                  char *err, size_t errlen);
