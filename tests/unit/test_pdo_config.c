/* SPDX-License-Identifier: MIT */
/*
 * The PDO layout keys of cogw.json (docs/config.md "PDO layouts"): "pdo"
 * and "pdo_scan_max" per line, "pdo", "eds" and "types" per node; the
 * layout a node's DCF/EDS gives (valid PDOs only, $NODEID COB-IDs, dummy
 * entries, types and access from the file, "types" over them); every bad
 * value refused with its JSON path.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "apps/common/config.h"
#include "apps/common/pdo_config.h"
#include "core/od.h"
#include "unity.h"

static cogw_config cfg;
static char err[512];
static char dir[] = "/tmp/cogw-pdo-XXXXXX";

void setUp(void)
{
	memset(&cfg, 0, sizeof(cfg));
	err[0] = '\0';
}

void tearDown(void)
{
	cogw_config_free(&cfg);
}

#define LINE(extra) "{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5" extra "}"
#define CFG1(extra) "{\"lines\": [" LINE(extra) "]}"
#define MGR ", \"manager\": {}"

/* A device file of a node: TPDO 1 event-driven with an event timer,
 * TPDO 2 invalid (its broken mapping is not read), TPDO 4 synchronous
 * (TPDO 3 absent), RPDO 1 with a dummy entry; COB-IDs with $NODEID. */
static const char device_file[] =
	"[FileInfo]\nFileName=dev.eds\n[DeviceInfo]\nVendorNumber=0x42\n"
	"[1000]\nParameterName=Device type\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x191\n"
	/* TPDO 1 */
	"[1800]\nObjectType=0x9\nSubNumber=6\n"
	"[1800sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=6\n"
	"[1800sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x180\n"
	"[1800sub2]\nDataType=0x0005\nAccessType=rw\nDefaultValue=254\n"
	"[1800sub3]\nDataType=0x0006\nAccessType=rw\nDefaultValue=50\n"
	"[1800sub5]\nDataType=0x0006\nAccessType=rw\nDefaultValue=100\nParameterValue=250\n"
	"[1800sub6]\nDataType=0x0005\nAccessType=rw\nDefaultValue=0\n"
	"[1A00]\nObjectType=0x9\nSubNumber=3\n"
	"[1A00sub0]\nDataType=0x0005\nAccessType=rw\nDefaultValue=2\n"
	"[1A00sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x60000108\n"
	"[1A00sub2]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x64010110\n"
	/* TPDO 2: invalid; its mapping of 0 bits would be refused if read */
	"[1801]\nObjectType=0x9\nSubNumber=3\n"
	"[1801sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n"
	"[1801sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x80000280\n"
	"[1801sub2]\nDataType=0x0005\nAccessType=rw\nDefaultValue=255\n"
	"[1A01]\nObjectType=0x9\nSubNumber=2\n"
	"[1A01sub0]\nDataType=0x0005\nAccessType=rw\nDefaultValue=1\n"
	"[1A01sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x70000000\n"
	/* TPDO 4, synchronous every 2nd SYNC */
	"[1803]\nObjectType=0x9\nSubNumber=3\n"
	"[1803sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n"
	"[1803sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x480+$NODEID\n"
	"[1803sub2]\nDataType=0x0005\nAccessType=rw\nDefaultValue=2\n"
	"[1A03]\nObjectType=0x9\nSubNumber=2\n"
	"[1A03sub0]\nDataType=0x0005\nAccessType=rw\nDefaultValue=1\n"
	"[1A03sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000020\n"
	/* RPDO 1 with a dummy byte */
	"[1400]\nObjectType=0x9\nSubNumber=3\n"
	"[1400sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n"
	"[1400sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x200\n"
	"[1400sub2]\nDataType=0x0005\nAccessType=rw\nDefaultValue=255\n"
	"[1600]\nObjectType=0x9\nSubNumber=4\n"
	"[1600sub0]\nDataType=0x0005\nAccessType=rw\nDefaultValue=3\n"
	"[1600sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x62000108\n"
	"[1600sub2]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x00050008\n"
	"[1600sub3]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x64110110\n"
	/* the mapped objects */
	"[2000]\nParameterName=Temperature\nDataType=0x0002\nAccessType=ro\nDefaultValue=0\n"
	"[6000]\nObjectType=0x8\nSubNumber=2\n"
	"[6000sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
	"[6000sub1]\nDataType=0x0005\nAccessType=ro\nPDOMapping=1\n"
	"[6200]\nObjectType=0x8\nSubNumber=2\n"
	"[6200sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
	"[6200sub1]\nDataType=0x0005\nAccessType=rww\nDefaultValue=0\n"
	"[6401]\nObjectType=0x8\nSubNumber=2\n"
	"[6401sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
	"[6401sub1]\nDataType=0x0003\nAccessType=ro\n"
	"[6411]\nObjectType=0x8\nSubNumber=2\n"
	"[6411sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
	"[6411sub1]\nDataType=0x0003\nAccessType=rww\nDefaultValue=0\n";

static void write_file(const char *name, const char *text)
{
	char path[128];
	snprintf(path, sizeof path, "%s/%s", dir, name);
	FILE *f = fopen(path, "w");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(strlen(text), fwrite(text, 1, strlen(text), f));
	TEST_ASSERT_EQUAL_INT(0, fclose(f));
}

static void load(const char *json)
{
	char path[128];
	snprintf(path, sizeof path, "%s/t.json", dir);
	write_file("t.json", json);
	int rc = cogw_config_load_file(&cfg, path, err, sizeof err);
	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
}

static void expect_error(const char *json, const char *msg)
{
	char path[128], want[600];
	snprintf(path, sizeof path, "%s/t.json", dir);
	write_file("t.json", json);
	int rc = cogw_config_load_file(&cfg, path, err, sizeof err);
	snprintf(want, sizeof want, msg, path, dir);
	TEST_ASSERT_EQUAL_INT(-EINVAL, rc);
	TEST_ASSERT_EQUAL_STRING(want, err);
	TEST_ASSERT_EQUAL_size_t(0, cfg.n_lines);
}

static const cogw_node *node0(void)
{
	TEST_ASSERT_EQUAL_size_t(1, cfg.lines[0].n_nodes);
	return &cfg.lines[0].nodes[0];
}

static void test_defaults_off_and_eight(void)
{
	load(CFG1(", \"nodes\": [{\"id\": 9}]"));
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_OFF, cfg.lines[0].pdo);
	TEST_ASSERT_EQUAL_UINT16(8, cfg.lines[0].pdo_scan_max);
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_OFF, node0()->pdo);
	TEST_ASSERT_FALSE(cogw_node_pdo_kept(node0()));
}

static void test_node_inherits_and_overrides_the_line(void)
{
	load(CFG1(
		", \"pdo\": \"learn\", \"pdo_scan_max\": 512" MGR
		", \"nodes\": [{\"id\": 9}, {\"id\": 10, \"pdo\": \"off\"}, {\"id\": 11, \"pdo\": "
		"\"auto\"}]"));
	const cogw_line_config *l = &cfg.lines[0];
	TEST_ASSERT_EQUAL_UINT16(512, l->pdo_scan_max);
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_LEARN, l->nodes[0].pdo);
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_OFF, l->nodes[1].pdo);
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_AUTO, l->nodes[2].pdo);
	TEST_ASSERT_TRUE(cogw_node_pdo_scanned(&l->nodes[0]));
	TEST_ASSERT_FALSE(cogw_node_pdo_kept(&l->nodes[1]));
	TEST_ASSERT_TRUE(cogw_node_pdo_scanned(&l->nodes[2]));
}

static void test_bad_values_refused_with_path(void)
{
	expect_error(CFG1(", \"pdo\": \"on\""),
		     "%s: lines[0].pdo: \"on\": expected \"off\", \"learn\" (learn the slaves' PDO "
		     "layouts) or \"auto\" (learn and mirror them)");
	expect_error(CFG1(", \"pdo\": true"), "%s: lines[0].pdo: expected a string, got a boolean");
	expect_error(CFG1(", \"pdo_scan_max\": 0"),
		     "%s: lines[0].pdo_scan_max: 0 is out of range 1..512");
	expect_error(CFG1(", \"pdo_scan_max\": 513"),
		     "%s: lines[0].pdo_scan_max: 513 is out of range 1..512");
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"pdo\": \"LEARN\"}]"),
		     "%s: lines[0].nodes[0].pdo: \"LEARN\": expected \"off\", \"learn\" (learn the "
		     "slaves' PDO layouts) or \"auto\" (learn and mirror them)");
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": [\"INTEGER16\"]}]"),
		     "%s: lines[0].nodes[0].types: expected an object {\"6401:1\": \"INTEGER16\", "
		     "...}, got an array");
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": {\"6401\": \"INTEGER16\"}}]"),
		     "%s: lines[0].nodes[0].types.6401: not an object \"INDEX:SUB\" (index hex, "
		     "e.g. \"6401:1\")");
	expect_error(
		CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": {\"16401:1\": \"INTEGER16\"}}]"),
		"%s: lines[0].nodes[0].types.16401:1: not an object \"INDEX:SUB\" (index hex, "
		"e.g. \"6401:1\")");
	expect_error(
		CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": {\"6401:256\": \"INTEGER16\"}}]"),
		"%s: lines[0].nodes[0].types.6401:256: not an object \"INDEX:SUB\" (index hex, "
		"e.g. \"6401:1\")");
	expect_error(
		CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": {\"6401:1\": \"INT16\"}}]"),
		"%s: lines[0].nodes[0].types.6401:1: \"INT16\" is not a CiA 301 data type name "
		"(e.g. \"INTEGER16\", \"REAL32\")");
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"types\": {\"6401:1\": \"INTEGER16\", "
			      "\"0x6401:0x01\": \"INTEGER8\"}}]"),
		     "%s: lines[0].nodes[0].types: object 6401:1 is named twice");
	/* the scan is a step of the manager's boot */
	expect_error(
		CFG1(", \"pdo\": \"learn\", \"nodes\": [{\"id\": 9}]"),
		"%s: lines[0].nodes[0]: node 9 learns its PDO layout by SDO (pdo \"learn\", no "
		"config.dcf or eds), a step of the manager's boot: the line has no \"manager\"");
	expect_error(
		CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"none.eds\"}]"),
		"%s: lines[0].nodes[0].eds: %s/none.eds: cannot open: No such file or directory");
}

static void test_types_without_file(void)
{
	load(CFG1(MGR ", \"pdo\": \"learn\", \"nodes\": [{\"id\": 9, \"types\": {\"6401:2\": "
		      "\"INTEGER16\", \"0x2000:0\": \"REAL32\", \"6401h:0x1\": \"INTEGER16\", "
		      "\"comment\": \"x\"}}]"));
	const cogw_node *n = node0();
	TEST_ASSERT_EQUAL_size_t(3, n->n_types);
	TEST_ASSERT_FALSE(n->pdo_from_file);
	/* sorted */
	TEST_ASSERT_EQUAL_HEX16(0x2000, n->types[0].index);
	TEST_ASSERT_EQUAL_UINT16(CO_T_REAL32, n->types[0].type);
	TEST_ASSERT_EQUAL_UINT8(1, n->types[1].sub);
	TEST_ASSERT_EQUAL_UINT8(2, n->types[2].sub);
	const co_pdo_layout_type *t = co_pdo_layout_type_find(n->types, n->n_types, 0x6401, 2);
	TEST_ASSERT_NOT_NULL(t);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER16, t->type);
	TEST_ASSERT_NULL(co_pdo_layout_type_find(n->types, n->n_types, 0x6401, 3));
}

static void check_device_layout(const cogw_node *n)
{
	const eds_pdo_file *f = &n->pdo_file;
	TEST_ASSERT_TRUE(n->pdo_from_file);
	TEST_ASSERT_EQUAL_UINT16(2, f->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(1, f->n[CO_PDO_RX]);

	const co_pdo_layout_pdo *t1 = &f->pdo[CO_PDO_TX][0];
	TEST_ASSERT_EQUAL_UINT16(1, t1->nr);
	TEST_ASSERT_EQUAL_HEX32(0x189, t1->cob);
	TEST_ASSERT_EQUAL_UINT8(254, t1->tt);
	TEST_ASSERT_EQUAL_UINT16(50, t1->inhibit);
	TEST_ASSERT_EQUAL_UINT16(250, t1->event_ms); /* ParameterValue over DefaultValue */
	TEST_ASSERT_EQUAL_UINT8(2, t1->n);
	TEST_ASSERT_EQUAL_UINT8(3, t1->bytes);
	TEST_ASSERT_EQUAL_HEX16(0x6000, t1->map[0].index);
	TEST_ASSERT_EQUAL_UINT8(1, t1->map[0].sub);
	TEST_ASSERT_EQUAL_UINT8(8, t1->map[0].bits);
	TEST_ASSERT_EQUAL_UINT16(CO_T_UNSIGNED8, t1->map[0].type);
	TEST_ASSERT_EQUAL_UINT8(CO_ACC_RO, t1->map[0].access);
	TEST_ASSERT_EQUAL_HEX16(0x6401, t1->map[1].index);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER16, t1->map[1].type);
	TEST_ASSERT_EQUAL_UINT8(16, t1->map[1].bits);

	/* TPDO 2 is invalid: TPDO 4 follows */
	const co_pdo_layout_pdo *t4 = &f->pdo[CO_PDO_TX][1];
	TEST_ASSERT_EQUAL_UINT16(4, t4->nr);
	TEST_ASSERT_EQUAL_HEX32(0x489, t4->cob);
	TEST_ASSERT_EQUAL_UINT8(2, t4->tt);
	TEST_ASSERT_EQUAL_UINT8(1, t4->n);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER32, t4->map[0].type);
	TEST_ASSERT_EQUAL_UINT8(4, t4->bytes);

	const co_pdo_layout_pdo *r1 = &f->pdo[CO_PDO_RX][0];
	TEST_ASSERT_EQUAL_HEX32(0x209, r1->cob);
	TEST_ASSERT_EQUAL_UINT8(255, r1->tt);
	TEST_ASSERT_EQUAL_UINT8(3, r1->n);
	TEST_ASSERT_EQUAL_UINT8(CO_ACC_RWW, r1->map[0].access);
	TEST_ASSERT_EQUAL_HEX16(0x0005, r1->map[1].index); /* dummy UNSIGNED8 */
	TEST_ASSERT_EQUAL_UINT16(CO_T_UNSIGNED8, r1->map[1].type);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER16, r1->map[2].type);
	TEST_ASSERT_EQUAL_UINT8(4, r1->bytes);
}

static void test_layout_from_eds(void)
{
	write_file("dev.eds", device_file);
	load(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"dev.eds\", \"types\": {\"2000:0\": "
		      "\"INTEGER32\"}}]"));
	check_device_layout(node0());
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_CONFIG_NONE, node0()->config.source);
	/* layout from the file even with pdo off: it costs nothing */
	TEST_ASSERT_EQUAL_UINT8(COGW_PDO_OFF, node0()->pdo);
	TEST_ASSERT_TRUE(cogw_node_pdo_kept(node0()));
	TEST_ASSERT_FALSE(cogw_node_pdo_scanned(node0()));
}

static void test_layout_from_config_dcf(void)
{
	write_file("dev.dcf", device_file);
	load(CFG1(MGR ", \"pdo\": \"learn\", \"nodes\": [{\"id\": 9, \"config\": {\"dcf\": "
		      "\"dev.dcf\"}, \"types\": {\"2000:0\": \"INTEGER32\"}}]"));
	check_device_layout(node0());
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_CONFIG_DCF, node0()->config.source);
	TEST_ASSERT_FALSE(cogw_node_pdo_scanned(node0()));
}

/* The file's own type for 2000h (INTEGER8) does not fit its 32-bit
 * mapping; without the override that is refused with the file's name. */
static void test_mapping_that_does_not_fit_its_type(void)
{
	write_file("dev.eds", device_file);
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"dev.eds\"}]"),
		     "%s: lines[0].nodes[0].eds: %s/dev.eds: TPDO 4 (mapping 1A03h): sub 1: "
		     "2000:00 is mapped with 32 bits, but it is INTEGER8 (8 bits)");
}

static void test_eds_with_download_is_scanned_and_typed(void)
{
	write_file("dev.eds", device_file);
	load(CFG1(MGR ", \"pdo\": \"learn\", \"nodes\": [{\"id\": 9, \"eds\": \"dev.eds\", "
		      "\"config\": {\"entries\": [{\"index\": \"0x1800\", \"sub\": 5, \"type\": "
		      "\"UNSIGNED16\", \"value\": 10}]}, \"types\": {\"2000:0\": \"REAL32\"}}]"));
	const cogw_node *n = node0();
	TEST_ASSERT_FALSE(n->pdo_from_file);
	TEST_ASSERT_TRUE(cogw_node_pdo_scanned(n));
	TEST_ASSERT_EQUAL_UINT16(0, n->pdo_file.n[CO_PDO_TX]);
	const co_pdo_layout_type *t = co_pdo_layout_type_find(n->types, n->n_types, 0x6401, 1);
	TEST_ASSERT_NOT_NULL(t);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER16, t->type);
	TEST_ASSERT_EQUAL_UINT8(CO_ACC_RO, t->access);
	t = co_pdo_layout_type_find(n->types, n->n_types, 0x2000, 0);
	TEST_ASSERT_EQUAL_UINT16(CO_T_REAL32, t->type); /* the override wins */
	TEST_ASSERT_EQUAL_UINT8(CO_ACC_RO, t->access);  /* the file's access stays */
}

static void test_eds_and_config_dcf_refused(void)
{
	write_file("dev.eds", device_file);
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"dev.eds\", \"config\": "
			      "{\"dcf\": \"dev.eds\"}, \"types\": {\"2000:0\": \"INTEGER32\"}}]"),
		     "%s: lines[0].nodes[0].eds: node 9 has \"config\": {\"dcf\": ...} too, which "
		     "describes the configured device: give one of them");
}

static void test_unusable_mappings_refused(void)
{
	static const char over64[] =
		"[1800]\nObjectType=0x9\nSubNumber=2\n"
		"[1800sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
		"[1800sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x181\n"
		"[1A00]\nObjectType=0x9\nSubNumber=4\n"
		"[1A00sub0]\nDataType=0x0005\nAccessType=rw\nDefaultValue=3\n"
		"[1A00sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000120\n"
		"[1A00sub2]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000220\n"
		"[1A00sub3]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000308\n";
	static const char missing[] =
		"[1400]\nObjectType=0x9\nSubNumber=2\n"
		"[1400sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
		"[1400sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x201\n"
		"[1600]\nObjectType=0x9\nSubNumber=1\n"
		"[1600sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n";
	write_file("over.eds", over64);
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"over.eds\"}]"),
		     "%s: lines[0].nodes[0].eds: %s/over.eds: TPDO 1 (mapping 1A00h): the entries "
		     "map more than 64 bits");
	write_file("missing.eds", missing);
	expect_error(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"missing.eds\"}]"),
		     "%s: lines[0].nodes[0].eds: %s/missing.eds: RPDO 1 (mapping 1600h): sub0 = 2 "
		     "but sub 1 has no value");
}

/* A changed layout file is a changed node: the reload changes it at run
 * time (its layout is learnt again at its boot); a changed pdo_scan_max
 * needs a restart (the table is sized at start-up). */
static void test_reload_sees_a_changed_layout(void)
{
	char path[128], what[256];
	cogw_config next;
	write_file("dev.eds", device_file);
	load(CFG1(MGR ", \"nodes\": [{\"id\": 9, \"eds\": \"dev.eds\", \"types\": {\"2000:0\": "
		      "\"INTEGER32\"}}]"));
	memset(&next, 0, sizeof next);
	snprintf(path, sizeof path, "%s/t.json", dir);
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_file(&next, path, err, sizeof err));
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cfg, &next, what, sizeof what));
	cogw_config_free(&next);

	char changed[sizeof device_file + 8];
	snprintf(changed, sizeof changed, "%s", device_file);
	char *at = strstr(changed, "DefaultValue=254");
	TEST_ASSERT_NOT_NULL(at);
	at[strlen("DefaultValue=25")] = '3';
	write_file("dev.eds", changed);
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_file(&next, path, err, sizeof err));
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cfg, &next, what, sizeof what));
	static cogw_node_diff nd;
	const cogw_node *cur[128];
	cogw_nodes_by_id(&cfg.lines[0], cur);
	TEST_ASSERT_TRUE(cogw_config_node_diff(cur, &cfg.lines[0], &next.lines[0], 0, &nd));
	TEST_ASSERT_EQUAL_size_t(1, nd.n);
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_CHANGED, nd.change[0].kind);
	TEST_ASSERT_EQUAL_UINT8(9, nd.change[0].id);
	cogw_config_free(&next);

	write_file("dev.eds", device_file);
	write_file("t.json", CFG1(MGR ", \"pdo_scan_max\": 4, \"nodes\": [{\"id\": 9, \"eds\": "
				      "\"dev.eds\", \"types\": {\"2000:0\": \"INTEGER32\"}}]"));
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_file(&next, path, err, sizeof err));
	TEST_ASSERT_FALSE(cogw_config_reload_check(&cfg, &next, what, sizeof what));
	TEST_ASSERT_EQUAL_STRING("lines[0].pdo_scan_max: needs a restart", what);
	cogw_config_free(&next);
}

int main(void)
{
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	UNITY_BEGIN();
	RUN_TEST(test_defaults_off_and_eight);
	RUN_TEST(test_node_inherits_and_overrides_the_line);
	RUN_TEST(test_bad_values_refused_with_path);
	RUN_TEST(test_types_without_file);
	RUN_TEST(test_layout_from_eds);
	RUN_TEST(test_layout_from_config_dcf);
	RUN_TEST(test_mapping_that_does_not_fit_its_type);
	RUN_TEST(test_eds_with_download_is_scanned_and_typed);
	RUN_TEST(test_eds_and_config_dcf_refused);
	RUN_TEST(test_unusable_mappings_refused);
	RUN_TEST(test_reload_sees_a_changed_layout);
	int rc = UNITY_END();
	char cmd[64];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	(void)system(cmd);
	return rc;
}
