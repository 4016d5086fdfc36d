/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/nv.c - the simulated device's non-volatile memory: what 1010h
 * "save" keeps across a "power cycle" (a restart of cosim with the same
 * --nv directory), and the node-ID stored by LSS "store configuration".
 *
 * Same image format as the daemon's own store (core/od_image.h, shared
 * with lines/line_store.c). One file per
 * part, <key>.comm (1000h-1FFFh) and <key>.app (2000h-FFFFh), so that
 * saving sub 2 or 3 keeps the other part (CiA 301 §7.5.2.13).
 *
 * Unlike the daemon, the simulator writes synchronously from its only
 * thread: a device that stalls for a few milliseconds while it writes its
 * flash is realistic, and nothing else waits on it. Loads check every
 * record against the OD (entry exists, length fits, value passes the
 * type/limit checks); bad ones are skipped and counted, never trusted.
 */
#include "apps/cosim/cosim.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/od_image.h"
#include "lines/file_atomic.h"

#define NV_FILE_MAX (1024u * 1024u)

static void nv_path(char *out, size_t n, const char *dir, const char *key, const char *ext)
{
	snprintf(out, n, "%s/%s.%s", dir, key, ext);
}

static int read_file(const char *path, uint8_t **out, size_t *len)
{
	FILE *f = fopen(path, "rb");
	uint8_t *buf;
	size_t n;

	if (!f)
		return -errno;
	buf = malloc(NV_FILE_MAX);
	if (!buf) {
		fclose(f);
		return -ENOMEM;
	}
	n = fread(buf, 1, NV_FILE_MAX, f);
	if (ferror(f)) {
		fclose(f);
		free(buf);
		return -EIO;
	}
	fclose(f);
	*out = buf;
	*len = n;
	return 0;
}

int cosim_nv_save(const co_od *od, const char *dir, const char *key, unsigned parts)
{
	static const struct {
		unsigned part;
		const char *ext;
	} files[] = { { COSIM_NV_COMM, "comm" }, { COSIM_NV_APP, "app" } };
	uint8_t *buf = malloc(NV_FILE_MAX);
	char path[520];
	int rc = 0;

	if (!buf)
		return -ENOMEM;
	for (size_t i = 0; i < 2 && !rc; i++) {
		if (!(parts & files[i].part))
			continue;
		long n = co_od_image_write(od, files[i].part, buf, NV_FILE_MAX);
		if (n < 0) {
			rc = (int)n;
			break;
		}
		nv_path(path, sizeof path, dir, key, files[i].ext);
		rc = file_write_atomic(path, buf, (size_t)n, 0644);
	}
	free(buf);
	return rc;
}

int cosim_nv_load(co_od *od, const char *dir, const char *key, unsigned *loaded, unsigned *skipped)
{
	static const char *const exts[] = { "comm", "app" };
	char path[520];

	*loaded = *skipped = 0;
	for (size_t i = 0; i < 2; i++) {
		uint8_t *buf = NULL;
		size_t len = 0;
		unsigned l, s;
		nv_path(path, sizeof path, dir, key, exts[i]);
		int rc = read_file(path, &buf, &len);
		if (rc == -ENOENT)
			continue;
		if (rc)
			return rc;
		rc = co_od_image_apply(od, buf, len,
				       CO_OD_IMAGE_SET_DEFAULT | CO_OD_IMAGE_SET_VALUE, &l, &s);
		free(buf);
		if (rc) {
			(*skipped)++; /* not one of our files: ignored whole */
			continue;
		}
		*loaded += l;
		*skipped += s;
	}
	return 0;
}

int cosim_nv_erase(const char *dir, const char *key, unsigned parts)
{
	char path[520];
	int rc = 0;

	if (parts & COSIM_NV_COMM) {
		nv_path(path, sizeof path, dir, key, "comm");
		if (unlink(path) < 0 && errno != ENOENT)
			rc = -errno;
	}
	if (parts & COSIM_NV_APP) {
		nv_path(path, sizeof path, dir, key, "app");
		if (unlink(path) < 0 && errno != ENOENT && !rc)
			rc = -errno;
	}
	return rc;
}

int cosim_nv_save_node_id(const char *dir, const char *key, uint8_t node_id)
{
	char path[520], text[16];
	int n = snprintf(text, sizeof text, "%u\n", node_id);

	nv_path(path, sizeof path, dir, key, "lss");
	return file_write_atomic(path, text, (size_t)n, 0644);
}

int cosim_nv_load_node_id(const char *dir, const char *key, uint8_t *node_id)
{
	char path[520], text[16] = { 0 };
	FILE *f;
	unsigned v;

	nv_path(path, sizeof path, dir, key, "lss");
	f = fopen(path, "r");
	if (!f)
		return -errno;
	bool ok = fgets(text, sizeof text, f) && sscanf(text, "%u", &v) == 1 &&
		  ((v >= 1 && v <= 127) || v == 255);
	fclose(f);
	if (!ok)
		return -EINVAL;
	*node_id = (uint8_t)v;
	return 0;
}
