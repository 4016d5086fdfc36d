/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_config_unknown.c - a line's "unknown_nodes"
 * (docs/config.md "Unknown nodes"): the keys, every class of bad value,
 * the device files of the "boot" policy (identity, concise DCF per
 * node-ID, 1F22h:n room for the node-IDs the line may adopt), and the
 * match of an identity against them (manager/manager_adopt.h).
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "unity.h"

#include "apps/common/config.h"
#include "core/cdcf.h"
#include "core/cfgmgr.h"
#include "mailbox/proto.h"
#include "manager/manager_adopt.h"

static cogw_config cfg;
static char err[512];
static char dir[64];

/* Two device files written by the test: one whose values do not depend on
 * the node-ID, one with $NODEID. */
static const char eds_fixed[] =
	"[FileInfo]\nFileName=fixed.eds\n\n"
	"[1000]\nParameterName=Device type\nObjectType=0x7\n"
	"DataType=0x0007\nAccessType=ro\nDefaultValue=0x00030191\n\n"
	"[1017]\nParameterName=Producer heartbeat time\nObjectType=0x7\n"
	"DataType=0x0006\nAccessType=rw\nDefaultValue=200\n\n"
	"[1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=4\n\n"
	"[1018sub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\n"
	"AccessType=ro\nDefaultValue=3\n\n"
	"[1018sub1]\nParameterName=Vendor\nObjectType=0x7\nDataType=0x0007\n"
	"AccessType=ro\nDefaultValue=0x00000ABC\n\n"
	"[1018sub2]\nParameterName=Product\nObjectType=0x7\nDataType=0x0007\n"
	"AccessType=ro\nDefaultValue=0x12\n\n"
	"[1018sub3]\nParameterName=Revision\nObjectType=0x7\n"
	"DataType=0x0007\nAccessType=ro\nDefaultValue=0x00010002\n";
static const char eds_nodeid[] = "[FileInfo]\nFileName=nodeid.eds\n\n"
				 "[1000]\nParameterName=Device type\nObjectType=0x7\n"
				 "DataType=0x0007\nAccessType=ro\nDefaultValue=0x00020192\n\n"
				 "[2000]\nParameterName=Base\nObjectType=0x7\nDataType=0x0007\n"
				 "AccessType=rw\nDefaultValue=$NODEID+0x100\n";

static void write_file(const char *name, const char *text)
{
	char path[128];
	snprintf(path, sizeof path, "%s/%s", dir, name);
	FILE *f = fopen(path, "w");
	TEST_ASSERT_NOT_NULL(f);
	fputs(text, f);
	fclose(f);
}

static void remove_files(void)
{
	const char *names[] = { "a-fixed.eds", "b-nodeid.DCF", "notes.txt", "c-bad.eds" };
	char path[128];
	for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
		snprintf(path, sizeof path, "%s/%s", dir, names[i]);
		unlink(path);
	}
}

void setUp(void)
{
	memset(&cfg, 0, sizeof cfg);
	snprintf(dir, sizeof dir, "/tmp/cogw-unknown-XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
}

void tearDown(void)
{
	cogw_config_free(&cfg);
	remove_files();
	rmdir(dir);
}

/* A line (node-ID 5) with a manager and node 7, and this unknown_nodes. */
static int load(const char *unknown)
{
	char text[1024];
	snprintf(text, sizeof text,
		 "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5, "
		 "\"manager\": {}, \"nodes\": [{\"id\": 7}], \"unknown_nodes\": %s}]}",
		 unknown);
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof cfg);
	err[0] = '\0';
	return cogw_config_load_string(&cfg, text, "t.json", err, sizeof err);
}

static void assert_refused(const char *unknown, const char *words)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, load(unknown), unknown);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, words), err);
}

static void test_defaults_and_supervise(void)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, load("{}"), err);
	const cogw_unknown_config *u = &cfg.lines[0].unknown;
	TEST_ASSERT_EQUAL_UINT8(MBX_UNKNOWN_IGNORE, u->policy);
	TEST_ASSERT_EQUAL_UINT16(1500, u->heartbeat_ms);
	TEST_ASSERT_EQUAL_UINT16(100, u->sdo_timeout_ms);
	TEST_ASSERT_TRUE(u->identify); /* the line has a manager */
	TEST_ASSERT_EQUAL_size_t(0, u->n_devices);
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0,
		load("{\"policy\": \"supervise\", \"heartbeat_ms\": 3000, \"sdo_timeout_ms\": 40}"),
		err);
	u = &cfg.lines[0].unknown;
	TEST_ASSERT_EQUAL_UINT8(MBX_UNKNOWN_SUPERVISE, u->policy);
	TEST_ASSERT_EQUAL_UINT16(3000, u->heartbeat_ms);
	TEST_ASSERT_EQUAL_UINT16(40, u->sdo_timeout_ms);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, load("{\"identify\": false}"), err);
	TEST_ASSERT_FALSE(cfg.lines[0].unknown.identify);
}

static void test_bad_values_are_refused_with_their_path(void)
{
	assert_refused("{\"policy\": \"adopt\"}", "lines[0].unknown_nodes.policy");
	assert_refused("{\"policy\": 1}", "policy");
	assert_refused("{\"sdo_timeout_ms\": 0}", "sdo_timeout_ms");
	assert_refused("{\"sdo_timeout_ms\": 5001}", "sdo_timeout_ms");
	assert_refused("{\"heartbeat_ms\": 65536}", "heartbeat_ms");
	assert_refused("{\"heartbeat_ms\": -1}", "heartbeat_ms");
	assert_refused("{\"identify\": 1}", "identify");
	/* without a manager the line reads no identity unless told to */
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof cfg);
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0,
		cogw_config_load_string(
			&cfg,
			"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, "
			"\"node_id\": 5}]}",
			"t.json", err, sizeof err),
		err);
	TEST_ASSERT_FALSE(cfg.lines[0].unknown.identify);
	assert_refused("{\"policy\": \"ignore\", \"nodes\": 1}", "nodes");
	assert_refused("[]", "unknown_nodes");
	assert_refused("{\"devices_dir\": \"/tmp\"}", "only with");
	assert_refused("{\"policy\": \"boot\"}", "needs \"devices_dir\"");
	assert_refused("{\"policy\": \"boot\", \"devices_dir\": \"/nonexistent-cogw\"}",
		       "cannot open the directory");
	/* boot needs the line's manager */
	TEST_ASSERT_EQUAL_INT(
		-EINVAL, cogw_config_load_string(
				 &cfg,
				 "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, "
				 "\"node_id\": 5, \"unknown_nodes\": {\"policy\": \"boot\", "
				 "\"devices_dir\": \"/tmp\"}}]}",
				 "t.json", err, sizeof err));
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, "needs the line's \"manager\""), err);
}

static int load_boot(void)
{
	char u[200];
	snprintf(u, sizeof u, "{\"policy\": \"boot\", \"devices_dir\": \"%s\"}", dir);
	return load(u);
}

static void test_boot_reads_the_device_files(void)
{
	write_file("a-fixed.eds", eds_fixed);
	write_file("b-nodeid.DCF", eds_nodeid);
	write_file("notes.txt", "not a device file");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, load_boot(), err);
	const cogw_unknown_config *u = &cfg.lines[0].unknown;
	TEST_ASSERT_EQUAL_size_t(2, u->n_devices);
	const cogw_unknown_device *a = &u->devices[0], *b = &u->devices[1];
	TEST_ASSERT_NOT_NULL(strstr(a->file, "a-fixed.eds"));
	TEST_ASSERT_EQUAL_HEX32(0x00030191, a->ident[0]);
	TEST_ASSERT_EQUAL_HEX32(0xABC, a->ident[1]);
	TEST_ASSERT_EQUAL_HEX32(0x12, a->ident[2]);
	TEST_ASSERT_EQUAL_HEX32(0x00010002, a->ident[3]);
	TEST_ASSERT_TRUE(a->shared);
	TEST_ASSERT_TRUE(a->cdcf[9] == a->cdcf[100]);
	TEST_ASSERT_EQUAL_HEX32(0x00020192, b->ident[0]);
	TEST_ASSERT_EQUAL_HEX32(0, b->ident[1]); /* no 1018h: any */
	TEST_ASSERT_FALSE(b->shared);
	/* 2000h = $NODEID + 0x100, per node-ID (entry: index, sub, size, value) */
	TEST_ASSERT_EQUAL_size_t(4 + 11, b->cdcf_len[9]);
	TEST_ASSERT_EQUAL_HEX8(0x09, b->cdcf[9][4 + 7]);
	TEST_ASSERT_EQUAL_HEX8(0x01, b->cdcf[9][4 + 8]);
	TEST_ASSERT_EQUAL_HEX8(0x64, b->cdcf[100][4 + 7]);
	/* not for the configured node 7 nor the line's own node-ID 5 */
	TEST_ASSERT_NULL(b->cdcf[7]);
	TEST_ASSERT_NULL(b->cdcf[5]);
	/* 1F22h:n room for the node-IDs the line may adopt */
	const co_od_entry *e = co_od_find(cfg.lines[0].od, CO_CFGMGR_IDX_CDCF, 9);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_NOT_NULL(co_od_find(cfg.lines[0].od, CO_CFGMGR_IDX_CDCF, 127));
	TEST_ASSERT_NULL(co_od_find(cfg.lines[0].od, CO_CFGMGR_IDX_CDCF, 5));
}

static void test_a_bad_device_file_refuses_the_configuration(void)
{
	write_file("a-fixed.eds", eds_fixed);
	write_file("c-bad.eds", "[2000]\nDataType=0x0005\nAccessType=rw\n"
				"[2000]\nDataType=0x0005\nAccessType=rw\n");
	TEST_ASSERT_EQUAL_INT(-EINVAL, load_boot());
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, "c-bad.eds"), err);
}

static void test_identity_match(void)
{
	static uint8_t *const none[128] = { NULL };
	static const size_t lens[128] = { 0 };
	const mgr_ext_device devs[] = {
		{ .file = "exact",
		  .ident = { 0x191, 0xABC, 0x12, 0x10002 },
		  .cdcf = none,
		  .cdcf_len = lens },
		{ .file = "vendor", .ident = { 0, 0xABC, 0, 0 }, .cdcf = none, .cdcf_len = lens },
	};
	const uint32_t exact[4] = { 0x191, 0xABC, 0x12, 0x10002 };
	const uint32_t other_rev[4] = { 0x191, 0xABC, 0x12, 0x10003 };
	const uint32_t other_vendor[4] = { 0x191, 0xABD, 0x12, 0x10002 };
	TEST_ASSERT_EQUAL_STRING("exact", mgr_adopt_match(devs, 2, exact)->file);
	TEST_ASSERT_EQUAL_STRING("vendor", mgr_adopt_match(devs, 2, other_rev)->file);
	TEST_ASSERT_NULL(mgr_adopt_match(devs, 2, other_vendor));
	TEST_ASSERT_NULL(mgr_adopt_match(devs, 0, exact));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_defaults_and_supervise);
	RUN_TEST(test_bad_values_are_refused_with_their_path);
	RUN_TEST(test_boot_reads_the_device_files);
	RUN_TEST(test_a_bad_device_file_refuses_the_configuration);
	RUN_TEST(test_identity_match);
	return UNITY_END();
}
