/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_unknown.c - a line's "unknown_nodes" (docs/config.md
 * "unknown_nodes"): what the line does with a node it was not configured
 * for, and, for the "boot" policy, the device files such a node may match
 * by identity.
 *
 * Why the files are converted here, for every node-ID: the line thread
 * that adopts a node may neither read files nor allocate (docs/
 * architecture.md), and a device file's values may depend on the node-ID
 * ($NODEID). A file without $NODEID converts the same for every node-ID
 * and is kept once; the others once per node-ID the line may adopt.
 */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <cjson/cJSON.h>

#include "apps/common/config_read.h"
#include "apps/common/eds.h"
#include "apps/common/file_read.h"
#include "apps/common/json_util.h"
#include "core/cfgmgr.h"
#include "mailbox/proto.h"

static const char *const unknown_keys[] = { "policy",   "heartbeat_ms", "sdo_timeout_ms",
					    "identify", "devices_dir",  "comment",
					    NULL };

void cogw_unknown_config_free(cogw_unknown_config *u)
{
	for (size_t i = 0; u->devices && i < u->n_devices; i++) {
		cogw_unknown_device *d = &u->devices[i];
		for (unsigned id = 0; id < 128; id++)
			if (!d->shared || id == 0)
				free(d->cdcf[id]);
	}
	free(u->devices);
	u->devices = NULL;
	u->n_devices = 0;
}

static int parse_policy(struct ctx *c, const cJSON *o, const char *path, uint8_t *policy)
{
	char name[16] = "ignore", p[JSON_PATH_MAX];
	const json_at at = cfg_at(c, path);
	int rc = json_util_opt_string(o, "policy", &at, 1, name, sizeof name);
	if (rc)
		return rc;
	for (uint8_t i = MBX_UNKNOWN_IGNORE; i <= MBX_UNKNOWN_BOOT; i++)
		if (!strcmp(name, mbx_unknown_policy_to_string(i))) {
			*policy = i;
			return 0;
		}
	json_util_path_key(p, sizeof p, path, "policy");
	return cfg_fail(c, p, "\"%s\": expected \"ignore\", \"supervise\" or \"boot\"", name);
}

int cfg_parse_unknown(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	cogw_unknown_config *u = &l->unknown;
	char dir[COGW_FILE_NAME_MAX] = "", p[JSON_PATH_MAX];
	const json_at at = cfg_at(c, path);
	int rc;
	if ((rc = cfg_check_object(c, o, path, unknown_keys)) ||
	    (rc = parse_policy(c, o, path, &u->policy)) ||
	    (rc = cfg_opt_u16(c, o, "heartbeat_ms", path, (cfg_range){ 0, 65535 },
			      &u->heartbeat_ms)) ||
	    (rc = cfg_opt_u16(c, o, "sdo_timeout_ms", path,
			      (cfg_range){ 1, MBX_SCAN_TIMEOUT_MAX_MS }, &u->sdo_timeout_ms)) ||
	    (rc = json_util_opt_bool(o, "identify", &at, &u->identify)) ||
	    (rc = json_util_opt_string(o, "devices_dir", &at, 1, dir, sizeof dir)))
		return rc;
	json_util_path_key(p, sizeof p, path, "devices_dir");
	if (dir[0] && u->policy != MBX_UNKNOWN_BOOT)
		return cfg_fail(c, p, "only with \"policy\": \"boot\"");
	if (u->policy == MBX_UNKNOWN_BOOT && !dir[0])
		return cfg_fail(c, path, "\"policy\": \"boot\" needs \"devices_dir\"");
	if (u->policy == MBX_UNKNOWN_BOOT && !l->manager.enabled)
		return cfg_fail(c, path, "\"policy\": \"boot\" needs the line's \"manager\"");
	if (dir[0] && (dir[0] == '/' || !c->base_dir[0]
			       ? snprintf(u->devices_dir, sizeof u->devices_dir, "%s", dir)
			       : snprintf(u->devices_dir, sizeof u->devices_dir, "%s/%s",
					  c->base_dir, dir)) >= (int)sizeof u->devices_dir)
		return cfg_fail(c, p, "path too long");
	return 0;
}

/* ---- the device files ----------------------------------------------------- */

struct ident_pick {
	uint32_t ident[4];
};

/* 1000h and 1018h:1..3 as the file gives them. */
static void pick_identity(void *arg, const eds_entry *e)
{
	struct ident_pick *ip = arg;
	uint32_t v = 0;
	if (!e->value || e->size > 4)
		return;
	for (uint32_t i = 0; i < e->size; i++)
		v |= (uint32_t)e->value[i] << (8 * i);
	if (e->index == 0x1000 && e->sub == 0)
		ip->ident[0] = v;
	else if (e->index == 0x1018 && e->sub >= 1 && e->sub <= 3)
		ip->ident[e->sub] = v;
}

/* A device file's text, read once for all its conversions. */
struct device_text {
	const char *path;
	const uint8_t *text;
	size_t len;
};

/* d's concise DCF for node-ID `node` into dev's slot; ip: its identity
 * too (NULL: not wanted). */
static int convert(struct ctx *c, const struct device_text *t, uint8_t node, struct ident_pick *ip,
		   cogw_unknown_device *dev)
{
	eds_options opts = { .node_id = node,
			     .on_entry = ip ? pick_identity : NULL,
			     .entry_arg = ip };
	eds_result res;
	int rc = eds_convert_opts((const char *)t->text, t->len, t->path, &opts, &res);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return cfg_fail(c, t->path, "%s", res.err);
	dev->cdcf[node] = res.cdcf;
	dev->cdcf_len[node] = res.len;
	return 0;
}

/* Node-IDs the line may adopt: neither configured nor its own. */
static bool adoptable(const cogw_line_config *l, unsigned id)
{
	if (id == l->node_id)
		return false;
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == id)
			return false;
	return true;
}

static int load_device(struct ctx *c, cogw_line_config *l, const char *file, cogw_unknown_device *d)
{
	uint8_t *text = NULL;
	size_t len = 0;
	struct ident_pick ip = { { 0 } };
	int rc = cogw_file_read(file, EDS_FILE_MAX, &text, &len, c->msg, sizeof c->msg);
	if (rc)
		return rc;
	const struct device_text t = { file, text, len };
	snprintf(d->file, sizeof d->file, "%s", file);
	if ((rc = convert(c, &t, 1, &ip, d)) || (rc = convert(c, &t, 2, NULL, d)))
		goto out;
	memcpy(d->ident, ip.ident, sizeof d->ident);
	d->shared = d->cdcf_len[1] == d->cdcf_len[2] &&
		    !memcmp(d->cdcf[1], d->cdcf[2], d->cdcf_len[1]);
	if (d->shared) {
		free(d->cdcf[2]);
		d->cdcf[0] = d->cdcf[1]; /* the one buffer, freed once */
		for (unsigned id = 1; id < 128; id++) {
			d->cdcf[id] = d->cdcf[0];
			d->cdcf_len[id] = d->cdcf_len[1];
		}
		goto out;
	}
	for (unsigned id = 3; id < 128 && !rc; id++)
		if (adoptable(l, id))
			rc = convert(c, &t, (uint8_t)id, NULL, d);
out:
	free(text);
	return rc;
}

static bool device_file(const char *name)
{
	const char *dot = strrchr(name, '.');
	return dot && (!strcasecmp(dot, ".eds") || !strcasecmp(dot, ".dcf"));
}

static int cmp_names(const void *a, const void *b)
{
	return strcmp(a, b);
}

/* The *.eds and *.dcf files of the directory, sorted (the first file of an
 * identity wins, whatever order readdir gives). */
static int list_files(struct ctx *c, const char *dir, char (*names)[COGW_FILE_NAME_MAX], size_t *n)
{
	DIR *dp = opendir(dir);
	struct dirent *de;
	int rc = 0;
	*n = 0;
	if (!dp)
		return cfg_fail(c, dir, "cannot open the directory: %s", strerror(errno));
	while (!rc && (de = readdir(dp))) {
		if (!device_file(de->d_name))
			continue;
		if (*n == COGW_UNKNOWN_DEVICES_MAX)
			rc = cfg_fail(c, dir, "more than %u device files",
				      COGW_UNKNOWN_DEVICES_MAX);
		else if (snprintf(names[*n], COGW_FILE_NAME_MAX, "%s/%s", dir, de->d_name) >=
			 (int)COGW_FILE_NAME_MAX)
			rc = cfg_fail(c, dir, "%s: path too long", de->d_name);
		else
			(*n)++;
	}
	closedir(dp);
	qsort(names, *n, COGW_FILE_NAME_MAX, cmp_names);
	return rc;
}

/* 1F22h:n for every node-ID the line may adopt, with room for the largest
 * concise DCF of the directory (allocated now: the line thread writes it
 * when it adopts the node). */
static int add_cdcf_room(struct ctx *c, const char *path, cogw_line_config *l)
{
	size_t cap = 0;
	for (size_t i = 0; i < l->unknown.n_devices; i++)
		for (unsigned id = 1; id < 128; id++)
			if (l->unknown.devices[i].cdcf_len[id] > cap)
				cap = l->unknown.devices[i].cdcf_len[id];
	for (unsigned id = 1; id < 128 && cap; id++) {
		if (!adoptable(l, id))
			continue;
		int rc = co_od_add_cfgmgr_node(l->od, (uint8_t)id, (uint32_t)cap);
		if (rc == -ENOMEM)
			return rc;
		if (rc)
			return cfg_fail(c, path, "cannot add 1F22h:%u (%s)", id, strerror(-rc));
	}
	return 0;
}

int cfg_unknown_objects(struct ctx *c, const char *path, cogw_line_config *l)
{
	cogw_unknown_config *u = &l->unknown;
	char(*names)[COGW_FILE_NAME_MAX];
	size_t n = 0;
	int rc;
	if (u->policy != MBX_UNKNOWN_BOOT)
		return 0;
	if (!(names = calloc(COGW_UNKNOWN_DEVICES_MAX, sizeof names[0])))
		return -ENOMEM;
	rc = list_files(c, u->devices_dir, names, &n);
	if (!rc && n && !(u->devices = calloc(n, sizeof u->devices[0])))
		rc = -ENOMEM;
	for (size_t i = 0; !rc && i < n; i++) {
		u->n_devices = i + 1; /* freed with the config, also half-loaded */
		rc = load_device(c, l, names[i], &u->devices[i]);
	}
	free(names);
	return rc ? rc : add_cdcf_room(c, path, l);
}
