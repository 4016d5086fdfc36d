/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/log.c - the leaves every other cosim file uses: the log line
 * and the CRC-32 of a program image. Calls nothing else in cosim, so the
 * files above it (device.c, program.c, sim.c, main.c) form a tree.
 */
#include <stdarg.h>
#include <stdio.h>

#include "apps/cosim/cosim.h"

void cosim_log(bool quiet, const char *fmt, ...)
{
	va_list ap;

	if (quiet)
		return;
	va_start(ap, fmt);
	fputs("cosim: ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

uint32_t cosim_crc32(const uint8_t *data, size_t len)
{
	uint32_t crc = 0xFFFFFFFFu;

	for (size_t i = 0; i < len; i++) {
		crc ^= data[i];
		for (int b = 0; b < 8; b++)
			crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
	}
	return ~crc;
}
