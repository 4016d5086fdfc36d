/* SPDX-License-Identifier: MIT */
/*
 * core/store_file.h - the integrity trailer of a saved parameter file
 * (1010h "save", CiA 301 §7.5.2.13). No I/O: the caller owns buffer and
 * file.
 *
 * A saved file is an od_image (core/od_image.h: "COGWOD1\n" + records),
 * then 24 bytes (little-endian):
 *     "COGWSUM1" | u32 generation | u32 set | u32 image length | u32 crc
 * crc = CRC-32 (IEEE 802.3, reflected, as zlib) over the image and the 12
 * bytes generation..length. A truncated file, a bit flip or a file from
 * another writer fails the check and is not applied at all (a truncated
 * image must not half-apply, a flipped bit must not load as another
 * value).
 *
 * Generations make a save of several files atomic as a whole: every file
 * written by one save carries the same generation (one more than any file
 * on disk) and, in `set`, the parts written together. A reader takes the
 * file with the highest generation; if its set names a part whose file
 * does not carry the same generation, the save was cut between two files
 * (a kill or a power cut between the renames): the set is torn and must
 * not be applied (co_store_file_torn()).
 */
#ifndef COGW_CORE_STORE_FILE_H
#define COGW_CORE_STORE_FILE_H

#include <stddef.h>
#include <stdint.h>

#define CO_STORE_FILE_TRAILER 24u

typedef struct co_store_file_info {
	uint32_t generation;
	uint32_t set;     /* parts (CO_OD_IMAGE_*) saved together */
	size_t image_len; /* the od_image at the start of the buffer */
} co_store_file_info;

/* CRC-32 (IEEE, reflected 0xEDB88320, init and final xor 0xFFFFFFFF);
 * continue with the previous result (start with 0). */
uint32_t co_crc32(uint32_t crc, const void *data, size_t len);

/* Append the trailer to the image_len bytes at buf (cap bytes of room).
 * Returns the file length, or -EMSGSIZE. */
long co_store_file_seal(uint8_t *buf, size_t image_len, size_t cap, uint32_t generation,
			uint32_t set);

/* Check a file's content. Returns 0 (info filled), -ENODATA (no trailer:
 * not a sealed file, e.g. truncated), -EBADMSG (trailer present but the
 * length or the checksum is wrong). */
int co_store_file_check(const uint8_t *buf, size_t len, co_store_file_info *info);

/* Given the infos of the files of one parameter set (present[i] = 0 for a
 * file that does not exist), is the newest save torn? part[i] is the
 * CO_OD_IMAGE_* part file i holds. Returns 1 torn, 0 consistent. */
int co_store_file_torn(const co_store_file_info *info, const int *present, const unsigned *part,
		       size_t n);

#endif /* COGW_CORE_STORE_FILE_H */
