/* SPDX-License-Identifier: MIT */
/*
 * apps/common/node_config.c - a node's "config" in cogw.json to a concise
 * DCF (contract in node_config.h). All three sources end in the same
 * checked byte form, so the download step never sees where it came from.
 */
#include "apps/common/node_config.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/eds.h"
#include "apps/common/file_read.h"
#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "core/cdcf.h"

static const char *const config_keys[] = { "entries", "dcf",  "concise", "store",
					   "date",    "time", "comment", NULL };
static const char *const entry_keys[] = { "index", "sub", "type", "value", "comment", NULL };

const char *cogw_node_config_source_to_string(cogw_node_config_source s)
{
	switch (s) {
	case COGW_NODE_CONFIG_NONE:
		return "none";
	case COGW_NODE_CONFIG_ENTRIES:
		return "entries";
	case COGW_NODE_CONFIG_DCF:
		return "dcf";
	case COGW_NODE_CONFIG_CONCISE:
		return "concise";
	}
	return "?";
}

void cogw_node_config_free(cogw_node_config *nc)
{
	if (!nc)
		return;
	free(nc->cdcf);
	memset(nc, 0, sizeof(*nc));
}

bool cogw_node_config_equal(const cogw_node_config *a, const cogw_node_config *b)
{
	return a->source == b->source && a->store == b->store && a->verify == b->verify &&
	       a->date == b->date && a->time == b->time && a->cdcf_len == b->cdcf_len &&
	       (!a->cdcf_len || !memcmp(a->cdcf, b->cdcf, a->cdcf_len));
}

/* A copy of bytes read from `file` into nc->cdcf when they are a concise
 * DCF. */
static int cdcf_copy_checked(const char *file, const uint8_t *data, size_t len,
			     cogw_node_config *nc, char *err, size_t errlen)
{
	co_cdcf_diag d;
	char why[200];

	if (co_cdcf_check(data, len, NULL, &d)) {
		co_cdcf_diag_format(&d, why, sizeof(why));
		snprintf(err, errlen, "%s: not a concise DCF: %s", file, why);
		return -EINVAL;
	}
	nc->cdcf = malloc(len ? len : 1);
	if (!nc->cdcf)
		return -ENOMEM;
	memcpy(nc->cdcf, data, len);
	nc->cdcf_len = len;
	return 0;
}

int cogw_cdcf_load_file(const char *file, uint8_t **out, size_t *len, char *err, size_t errlen)
{
	uint8_t *buf;
	size_t got;
	int rc;

	*out = NULL;
	*len = 0;
	if ((rc = cogw_file_read(file, COGW_NODE_CONFIG_MAX, &buf, &got, err, errlen)))
		return rc;
	cogw_node_config nc = { 0 };
	rc = cdcf_copy_checked(file, buf, got, &nc, err, errlen);
	free(buf);
	*out = nc.cdcf;
	*len = nc.cdcf_len;
	return rc;
}

/* One entry of an "entries" list (e, at ep) added to w; val is the
 * scratch buffer of COGW_NODE_ENTRY_MAX bytes. */
static int add_listed_entry(const cJSON *e, const char *ep, co_cdcf_writer *w, uint8_t *val,
			    char *err, size_t errlen)
{
	char p[JSON_PATH_MAX], tname[32];
	const cJSON *v;
	uint16_t index;
	uint64_t sub = 0;
	co_type t;
	uint32_t len = 0;
	int rc;
	const json_at at = { ep, err, errlen };
	const json_at at_p = { p, err, errlen };

	if ((rc = json_util_check_object(e, &at, entry_keys)) ||
	    (rc = json_util_require(e, "index", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), ep, "index");
	if ((rc = json_od_parse_index(v, p, &index, err, errlen)) ||
	    (rc = json_util_opt_uint(e, "sub", &at, 0, 255, &sub)) ||
	    (rc = json_util_require(e, "type", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), ep, "type");
	if ((rc = json_util_string(v, &at_p, 1, tname, sizeof(tname))))
		return rc;
	if (!json_od_type_from_string(tname, &t))
		return json_util_fail(err, errlen, p,
				      "\"%s\" is not a CiA 301 data type name (e.g. "
				      "UNSIGNED16, VISIBLE_STRING)",
				      tname);
	if ((rc = json_util_require(e, "value", &at, &v)))
		return rc;
	json_util_path_key(p, sizeof(p), ep, "value");
	json_od_buf out = { val, COGW_NODE_ENTRY_MAX, 0 };
	if ((rc = json_od_parse_value(v, t, p, &out, err, errlen)))
		return rc;
	len = out.len;
	if (len == 0)
		return json_util_fail(err, errlen, p,
				      "empty value (a concise DCF entry needs at "
				      "least one byte)");
	rc = co_cdcf_writer_add(w, index, (uint8_t)sub, val, len);
	if (rc || w->len > COGW_NODE_CONFIG_MAX)
		return json_util_fail(err, errlen, ep, "configuration larger than %u bytes",
				      COGW_NODE_CONFIG_MAX);
	return 0;
}

/* One pass over the "entries" list into w (measuring when nc->cdcf is
 * still NULL). */
static int write_entries(const cJSON *list, const char *path, co_cdcf_writer *w, uint8_t *val,
			 char *err, size_t errlen)
{
	const cJSON *e;
	size_t i = 0;
	int rc;

	cJSON_ArrayForEach(e, list)
	{
		char ep[JSON_PATH_MAX];

		json_util_path_index(ep, sizeof(ep), path, i++);
		if ((rc = add_listed_entry(e, ep, w, val, err, errlen)))
			return rc;
	}
	return 0;
}

/* "entries": a JSON list, written with the cdcf writer in two passes
 * (measure, then fill) so the buffer is allocated once. */
static int parse_entries(const cJSON *list, const char *path, cogw_node_config *nc, char *err,
			 size_t errlen)
{
	uint8_t *val = NULL;
	co_cdcf_writer w;
	long n;
	int rc = 0;

	if (!cJSON_IsArray(list))
		return json_util_fail(err, errlen, path, "expected an array of entries, got %s",
				      json_util_kind(list));
	val = malloc(COGW_NODE_ENTRY_MAX);
	if (!val)
		return -ENOMEM;
	for (int pass = 0; pass < 2 && !rc; pass++) {
		co_cdcf_writer_init(&w, nc->cdcf, nc->cdcf_len);
		if ((rc = write_entries(list, path, &w, val, err, errlen)))
			break;
		n = co_cdcf_writer_finish(&w);
		if (n < 0) {
			rc = json_util_fail(err, errlen, path, "cannot build the concise DCF");
			break;
		}
		if (pass == 0) {
			nc->cdcf = malloc((size_t)n);
			if (!nc->cdcf) {
				rc = -ENOMEM;
				break;
			}
			nc->cdcf_len = (size_t)n;
		}
		nc->entries = w.count;
	}
	free(val);
	return rc;
}

/* base_dir/file into buf; false if it does not fit. */
static bool resolve(char *buf, size_t n, const char *base_dir, const char *file)
{
	size_t bl = base_dir ? strlen(base_dir) : 0, fl = strlen(file);

	if (file[0] == '/' || !bl) {
		if (fl >= n)
			return false;
		memcpy(buf, file, fl + 1);
		return true;
	}
	if (bl + 1 + fl >= n)
		return false;
	memcpy(buf, base_dir, bl);
	buf[bl] = '/';
	memcpy(buf + bl + 1, file, fl + 1);
	return true;
}

static const cogw_embedded_file *embedded_find(const cogw_embedded_file *files, const char *name)
{
	for (; files && files->name; files++)
		if (!strcmp(files->name, name))
			return files;
	return NULL;
}

/* The CiA 306 file `name` (resolved: nc->file) converted to a concise DCF
 * into nc; the sub-objects go to dev.pdo. The file comes from ld->files
 * first, else from disk through ld->read. */
static int convert_device_file(const char *name, cogw_device_ref dev, const cogw_load *ld,
			       cogw_node_config *nc, char *why, size_t whylen)
{
	const cogw_embedded_file *f = embedded_find(ld->files, name);
	cogw_file_bytes text = { f ? (const uint8_t *)f->data : NULL, f ? f->len : 0 };
	eds_options o = { .node_id = dev.node_id,
			  .on_entry = dev.pdo ? eds_pdo_reader_on_entry : NULL,
			  .entry_arg = dev.pdo };
	eds_result res = { 0 };
	int rc = f ? 0 : cogw_file_set_get(ld->read, nc->file, EDS_FILE_MAX, &text, why, whylen);

	if (rc)
		return rc;
	rc = eds_convert_opts((const char *)text.data, text.len, nc->file, &o, &res);
	if (rc)
		snprintf(why, whylen, "%s", res.err);
	nc->cdcf = res.cdcf;
	nc->cdcf_len = res.len;
	nc->entries = res.stats.entries;
	return rc;
}

int cogw_device_file_read(const cJSON *v, const char *path, cogw_device_ref dev,
			  const cogw_load *ld, char *file)
{
	char name[256], why[512];
	cogw_node_config nc = { 0 };
	int rc;
	const json_at at = { path, ld->err, ld->errlen };

	if ((rc = json_util_string(v, &at, 1, name, sizeof(name))))
		return rc;
	if (!resolve(nc.file, sizeof(nc.file), ld->base_dir, name))
		return json_util_fail(ld->err, ld->errlen, path, "file name longer than %zu bytes",
				      sizeof(nc.file) - 1);
	memcpy(file, nc.file, sizeof(nc.file));
	rc = convert_device_file(name, dev, ld, &nc, why, sizeof(why));
	free(nc.cdcf); /* read for its description only: nothing is downloaded */
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(ld->err, ld->errlen, path, "%s", why);
	return 0;
}

/* Which of "entries", "dcf" and "concise" v gives (*which, index into
 * srcs) and its value. */
static int pick_source(const cJSON *v, const char *path, const cJSON **src, int *which, char *err,
		       size_t errlen)
{
	static const char *const srcs[] = { "entries", "dcf", "concise" };
	char p[JSON_PATH_MAX];

	*src = NULL;
	for (int i = 0; i < 3; i++) {
		const cJSON *x = json_util_get(v, srcs[i]);

		if (!x)
			continue;
		if (*src) {
			json_util_path_key(p, sizeof(p), path, srcs[i]);
			return json_util_fail(err, errlen, p,
					      "only one of \"entries\", \"dcf\" and \"concise\" "
					      "(\"%s\" is given too)",
					      srcs[*which]);
		}
		*src = x;
		*which = i;
	}
	if (!*src)
		return json_util_fail(err, errlen, path,
				      "one of \"entries\", \"dcf\" or \"concise\" is required");
	return 0;
}

/* "store", "date" and "time" of a node's "config". */
static int parse_download_options(const cJSON *v, const char *path, cogw_node_config *nc, char *err,
				  size_t errlen)
{
	char p[JSON_PATH_MAX];
	uint64_t date = 0, time = 0;
	int rc;
	const json_at at = { path, err, errlen };

	if ((rc = json_util_opt_bool(v, "store", &at, &nc->store)) ||
	    (rc = json_util_opt_uint(v, "date", &at, 0, UINT32_MAX, &date)) ||
	    (rc = json_util_opt_uint(v, "time", &at, 0, 86399999, &time)))
		return rc;
	if (!json_util_get(v, "date") != !json_util_get(v, "time")) {
		json_util_path_key(p, sizeof(p), path, json_util_get(v, "date") ? "time" : "date");
		return json_util_fail(err, errlen, p,
				      "\"date\" and \"time\" go together (the expected 1020h:1/2)");
	}
	nc->verify = json_util_get(v, "date") != NULL;
	nc->date = (uint32_t)date;
	nc->time = (uint32_t)time;
	return 0;
}

/* A binary concise DCF file (resolved: nc->file) into nc. */
static int read_concise(const cogw_load *ld, cogw_node_config *nc, char *why, size_t whylen)
{
	cogw_file_bytes bytes;
	uint32_t count = 0;
	int rc = cogw_file_set_get(ld->read, nc->file, COGW_NODE_CONFIG_MAX, &bytes, why, whylen);

	if (!rc)
		rc = cdcf_copy_checked(nc->file, bytes.data, bytes.len, nc, why, whylen);
	if (rc)
		return rc;
	co_cdcf_check(nc->cdcf, nc->cdcf_len, &count, NULL);
	nc->entries = count;
	return 0;
}

/* A "dcf" or "concise" file (src, at p) read into nc, checked and charged
 * to ld->read; its message in why. */
static int read_config_file(const cJSON *src, const char *p, bool dcf, cogw_device_ref dev,
			    const cogw_load *ld, cogw_node_config *nc)
{
	char name[256], why[512];
	int rc;
	const json_at at = { p, ld->err, ld->errlen };

	if ((rc = json_util_string(src, &at, 1, name, sizeof(name))))
		return rc;
	if (!resolve(nc->file, sizeof(nc->file), ld->base_dir, name))
		return json_util_fail(ld->err, ld->errlen, p, "file name longer than %zu bytes",
				      sizeof(nc->file) - 1);
	nc->source = dcf ? COGW_NODE_CONFIG_DCF : COGW_NODE_CONFIG_CONCISE;
	if (dcf)
		rc = convert_device_file(name, dev, ld, nc, why, sizeof(why));
	else
		rc = read_concise(ld, nc, why, sizeof(why));
	if (!rc && nc->cdcf_len > COGW_NODE_CONFIG_MAX) {
		snprintf(why, sizeof(why), "%s: concise DCF larger than %u bytes", nc->file,
			 COGW_NODE_CONFIG_MAX);
		rc = -EINVAL;
	}
	/* the node's own concise DCF is held as long as the configuration */
	if (!rc)
		rc = cogw_file_set_charge(ld->read, nc->file, nc->cdcf_len, why, sizeof(why));
	if (rc) {
		cogw_node_config_free(nc);
		if (rc == -ENOMEM)
			return rc;
		json_util_fail(ld->err, ld->errlen, p, "%s", why);
		return -EINVAL;
	}
	return 0;
}

int cogw_node_config_parse(const cJSON *v, const char *path, cogw_device_ref dev,
			   const cogw_load *ld, cogw_node_config *nc)
{
	static const char *const srcs[] = { "entries", "dcf", "concise" };
	const cJSON *src = NULL;
	char p[JSON_PATH_MAX];
	int which = -1, rc;
	const json_at at = { path, ld->err, ld->errlen };

	memset(nc, 0, sizeof(*nc));
	if ((rc = json_util_check_object(v, &at, config_keys)) ||
	    (rc = pick_source(v, path, &src, &which, ld->err, ld->errlen)) ||
	    (rc = parse_download_options(v, path, nc, ld->err, ld->errlen)))
		return rc;
	json_util_path_key(p, sizeof(p), path, srcs[which]);
	if (which == 0) {
		nc->source = COGW_NODE_CONFIG_ENTRIES;
		rc = parse_entries(src, p, nc, ld->err, ld->errlen);
		if (rc)
			cogw_node_config_free(nc);
		return rc;
	}
	return read_config_file(src, p, which == 1, dev, ld, nc);
}
