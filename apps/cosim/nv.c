/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/nv.c - the simulated device's non-volatile memory: what 1010h
 * "save" keeps across a "power cycle" (a restart of cosim with the same
 * --nv directory), and the node-ID stored by LSS "store configuration".
 *
 * Same record format as the daemon's own store (lines/line_store.c), so a
 * file can be inspected with the same tools: "COGWOD1\n", then records
 * { u16 index, u8 sub, u32 len, len bytes }, little-endian. One file per
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

#include "core/store.h"

static const char nv_magic[8] = { 'C', 'O', 'G', 'W', 'O', 'D', '1', '\n' };

#define NV_FILE_MAX (1024u * 1024u)

static bool in_parts(const co_od_entry *e, unsigned parts)
{
	if (e->index == CO_STORE_IDX_SAVE || e->index == CO_STORE_IDX_LOAD)
		return false;
	if (!(e->access & (CO_ACC_WRITE | CO_ACC_PERSIST)) || (e->access & CO_ACC_CONST))
		return false;
	if (e->index >= 0x1000 && e->index <= 0x1FFF)
		return parts & COSIM_NV_COMM;
	return e->index >= 0x2000 && (parts & COSIM_NV_APP);
}

long cosim_nv_serialise(const co_od *od, unsigned parts, uint8_t *buf, size_t cap)
{
	size_t used = sizeof nv_magic;

	if (cap < used)
		return -EMSGSIZE;
	memcpy(buf, nv_magic, sizeof nv_magic);
	for (size_t i = 0; i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);
		if (!in_parts(e, parts))
			continue;
		if (cap - used < 7u + (size_t)e->size)
			return -EMSGSIZE;
		uint8_t *p = buf + used;
		co_put_le16(p, e->index);
		p[2] = e->sub;
		co_put_le32(p + 3, e->size);
		memcpy(p + 7, e->data, e->size);
		used += 7u + e->size;
	}
	return (long)used;
}

int cosim_nv_apply(co_od *od, const uint8_t *buf, size_t len, bool set_default,
		   bool set_value, unsigned *loaded, unsigned *skipped)
{
	size_t pos = sizeof nv_magic;

	*loaded = *skipped = 0;
	if (len < sizeof nv_magic || memcmp(buf, nv_magic, sizeof nv_magic) != 0)
		return -EINVAL;
	while (pos < len) {
		if (len - pos < 7) {
			(*skipped)++; /* truncated tail */
			break;
		}
		uint16_t index = co_get_le16(buf + pos);
		uint8_t sub = buf[pos + 2];
		uint32_t n = co_get_le32(buf + pos + 3);
		pos += 7;
		if (n > len - pos) {
			(*skipped)++;
			break;
		}
		co_od_entry *e = co_od_find(od, index, sub);
		if (!e || co_od_check_value(e, buf + pos, n) != 0) {
			(*skipped)++;
		} else {
			if (set_default)
				co_od_entry_set_default_bytes(e, buf + pos, n);
			if (set_value)
				co_od_entry_set_bytes(e, buf + pos, n);
			(*loaded)++;
		}
		pos += n;
	}
	return 0;
}

static void nv_path(char *out, size_t n, const char *dir, const char *key, const char *ext)
{
	snprintf(out, n, "%s/%s.%s", dir, key, ext);
}

/* Write buf to path atomically: temp file, fsync, rename. */
static int write_atomic(const char *path, const void *buf, size_t len)
{
	char tmp[600];
	int fd, rc = 0;

	snprintf(tmp, sizeof tmp, "%s.tmp", path);
	fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
	if (fd < 0)
		return -errno;
	const uint8_t *p = buf;
	size_t left = len;
	while (left > 0) {
		ssize_t w = write(fd, p, left);
		if (w < 0) {
			if (errno == EINTR)
				continue;
			rc = -errno;
			break;
		}
		p += w;
		left -= (size_t)w;
	}
	if (!rc && fsync(fd) < 0)
		rc = -errno;
	if (close(fd) < 0 && !rc)
		rc = -errno;
	if (!rc && rename(tmp, path) < 0)
		rc = -errno;
	if (rc)
		unlink(tmp);
	return rc;
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
		long n = cosim_nv_serialise(od, files[i].part, buf, NV_FILE_MAX);
		if (n < 0) {
			rc = (int)n;
			break;
		}
		nv_path(path, sizeof path, dir, key, files[i].ext);
		rc = write_atomic(path, buf, (size_t)n);
	}
	free(buf);
	return rc;
}

int cosim_nv_load(co_od *od, const char *dir, const char *key, unsigned *loaded,
		  unsigned *skipped)
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
		rc = cosim_nv_apply(od, buf, len, true, true, &l, &s);
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
	return write_atomic(path, text, (size_t)n);
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
