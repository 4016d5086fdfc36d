/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_ascii.c - cogw-ascii, the CiA 309-3 ASCII
 * gateway, end to end on vcan: real cogwd, real cosim devices, the real
 * gateway process, real UNIX and TCP sockets, and socat as the plain
 * client for the byte-exact transcripts (docs/ascii.md).
 *
 * One fixture for the whole group (one daemon, three devices, one
 * gateway), so that the VM boots once and the processes start once:
 *   vcan0 (network 1): tests/integration/config/ascii-types.json, node 5
 *   vcan1 (network 2): the same device file as node 6
 *   vcan2 (network 3): the same device file as node 7
 * Every test leaves the devices as it found them.
 */
#include "unity.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include "apps/cogw-ascii/ascii_value.h"
#include "mailbox/proto.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"

#define DEVICE "tests/integration/config/ascii-types.json"
#define TCP_PORT 14242
#define MAX_CONNECTIONS 24

/* The daemon: three lines, networks 1..3, several transfer slots (the
 * gateway is one mailbox client for all its connections). */
static const char daemon_json[] =
	"{\"version\": 1, \"mailbox\": {\"instance\": \"asc\", \"max_clients\": 16,"
	" \"transfer_slots\": 4, \"max_transfers_per_client\": 4, \"max_outstanding\": 32,"
	" \"rules\": [{\"uid\": 65534, \"access\": \"read\"}]},"
	" \"lines\": ["
	"  {\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 1,"
	"   \"heartbeat_consumers\": [{\"node_id\": 5, \"time_ms\": 1500}]},"
	"  {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 2},"
	"  {\"interface\": \"vcan2\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 3}]}";

static daemon_run d;
static cosim_run sims[3];
static pid_t gw_pid;
static char sock_path[108], gw_log[160], gw_conf[160];

/* ---- the gateway process ----------------------------------------------------- */

static int start_gateway(void)
{
	char json[1024];

	snprintf(gw_conf, sizeof gw_conf, "%s/ascii.json", d.dir);
	snprintf(sock_path, sizeof sock_path, "%s/ascii.sock", d.dir);
	snprintf(gw_log, sizeof gw_log, "%s/ascii.log", d.dir);
	snprintf(json, sizeof json,
		 "{\"version\": 1, \"daemon_config\": \"%s\", \"unix_socket\": \"%s\","
		 " \"tcp\": {\"address\": \"127.0.0.1\", \"port\": %d},"
		 " \"limits\": {\"max_connections\": %d, \"max_line\": 2097152,"
		 " \"max_outstanding\": 4, \"max_output\": 65536, \"request_timeout_ms\": 120000},"
		 " \"session\": {\"network\": 0, \"sdo_timeout_ms\": 5000}}",
		 d.config_path, sock_path, TCP_PORT, MAX_CONNECTIONS);
	if (write_text_file(gw_conf, json))
		return -1;
	const char *argv[] = { "build/san/bin/cogw-ascii", "--config", gw_conf, "-v", NULL };

	gw_pid = proc_spawn(argv, gw_log, NULL);
	if (gw_pid <= 0)
		return -1;
	return file_wait_contains(gw_log, "serving instance", 10000) ? 0 : -1;
}

static int stop_gateway(void)
{
	int st;

	if (gw_pid <= 0)
		return 0;
	st = proc_stop(gw_pid, SIGTERM, 10000);
	gw_pid = 0;
	return st;
}

/* ---- clients -------------------------------------------------------------------- */

static int connect_unix(void)
{
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

	snprintf(a.sun_path, sizeof a.sun_path, "%s", sock_path);
	if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) < 0) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	return fd;
}

static int connect_tcp(void)
{
	struct sockaddr_in a = { .sin_family = AF_INET,
				 .sin_port = htons(TCP_PORT),
				 .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
	int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);

	if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) < 0) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	return fd;
}

static void send_all(int fd, const char *text, size_t n)
{
	while (n) {
		ssize_t k = send(fd, text, n, MSG_NOSIGNAL);

		TEST_ASSERT_TRUE_MESSAGE(k > 0, "send to the gateway failed");
		text += k;
		n -= (size_t)k;
	}
}

static void send_text(int fd, const char *text)
{
	send_all(fd, text, strlen(text));
}

/* Read until `lines` line ends came (or timeout); returns the text
 * (static buffer grown as needed), NULL-safe. */
static char *recv_lines(int fd, unsigned lines, int timeout_ms)
{
	static char *buf;
	static size_t cap;
	size_t len = 0;
	unsigned seen = 0;
	uint64_t end = mono_ms() + (uint64_t)timeout_ms;

	if (!buf) {
		cap = 1 << 16;
		buf = malloc(cap);
	}
	buf[0] = '\0';
	while (seen < lines && mono_ms() < end) {
		struct pollfd p = { .fd = fd, .events = POLLIN };

		if (poll(&p, 1, (int)(end - mono_ms())) <= 0)
			break;
		if (len + 65536 + 1 > cap) {
			cap *= 2;
			buf = realloc(buf, cap);
		}
		ssize_t k = recv(fd, buf + len, 65536, 0);

		if (k <= 0)
			break;
		for (ssize_t i = 0; i < k; i++)
			seen += buf[len + (size_t)i] == '\n';
		len += (size_t)k;
		buf[len] = '\0';
	}
	return buf;
}

/* One command, one answer line (without its line end). */
static const char *ask(int fd, const char *cmd)
{
	static char line[512];
	char *got;

	send_text(fd, cmd);
	send_text(fd, "\n");
	got = recv_lines(fd, 1, 15000);
	snprintf(line, sizeof line, "%s", got);
	line[strcspn(line, "\r\n")] = '\0';
	return line;
}

/* socat as the client: input is sent, the gateway answers, socat's
 * output must be exactly `expected`, written with LF line ends: every
 * answer line ends with CR LF (docs/ascii.md "Commands"), so each LF of
 * `expected` stands for CR LF. */
static void transcript_bytes(const char *sock, const char *name, const char *input,
			     size_t input_len, const char *expected);

static void transcript(const char *name, const char *input, const char *expected)
{
	transcript_bytes(sock_path, name, input, strlen(input), expected);
}

static void transcript_at(const char *sock, const char *name, const char *input,
			  const char *expected)
{
	transcript_bytes(sock, name, input, strlen(input), expected);
}

static void transcript_bytes(const char *sock, const char *name, const char *input,
			     size_t input_len, const char *expected)
{
	char in_path[200], out_path[200], cmd[700];
	FILE *f;
	static char out[16384], want[16384 + 1024];
	size_t n, k = 0;

	for (const char *p = expected; *p && k < sizeof want - 2; p++) {
		if (*p == '\n' && (p == expected || p[-1] != '\r'))
			want[k++] = '\r';
		want[k++] = *p;
	}
	want[k] = '\0';
	snprintf(in_path, sizeof in_path, "%s/%s.in", d.dir, name);
	snprintf(out_path, sizeof out_path, "%s/%s.out", d.dir, name);
	f = fopen(in_path, "w");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(input_len, fwrite(input, 1, input_len, f));
	TEST_ASSERT_EQUAL_INT(0, fclose(f));
	snprintf(cmd, sizeof cmd, "timeout 60 socat -t 30 - UNIX-CONNECT:%s < %s > %s", sock,
		 in_path, out_path);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, system(cmd), "socat failed");
	f = fopen(out_path, "r");
	TEST_ASSERT_NOT_NULL(f);
	n = fread(out, 1, sizeof out - 1, f);
	fclose(f);
	out[n] = '\0';
	TEST_ASSERT_EQUAL_STRING_MESSAGE(want, out, name);
}

/* ---- the tests -------------------------------------------------------------------- */

/* Every type keyword on an object of its type: the device's default read
 * byte-exact, a new value written, read back, the default restored. */
static void test_every_type_keyword_byte_exact(void)
{
	transcript(
		"types",
		"set network 1\n"
		"set node 5\n"
		"[1] r 0x2100 0 b\n[2] r 0x2101 0 i8\n[3] r 0x2102 0 i16\n"
		"[4] r 0x2103 0 i32\n[5] r 0x2104 0 i64\n[6] r 0x2105 0 u8\n"
		"[7] r 0x2106 0 u16\n[8] r 0x2107 0 u32\n[9] r 0x2108 0 u64\n"
		"[10] r 0x2109 0 r32\n[11] r 0x210A 0 r64\n[12] r 0x210B 0 t\n"
		"[13] r 0x210C 0 td\n[14] r 0x210D 0 vs\n[15] r 0x210E 0 os\n"
		"[16] r 0x210F 0 us\n[17] r 0x2110 0 d\n[18] r 0x2107 0 x32\n"
		"[19] r 0x210E 0 hex\n[20] r 0x210E 0\n"
		"[21] w 0x2100 0 b 0\n[22] w 0x2101 0 i8 -128\n[23] w 0x2102 0 i16 32767\n"
		"[24] w 0x2103 0 i32 -2147483648\n[25] w 0x2104 0 i64 9223372036854775807\n"
		"[26] w 0x2105 0 u8 0x7f\n[27] w 0x2106 0 u16 1\n[28] w 0x2107 0 u32 4294967295\n"
		"[29] w 0x2108 0 u64 18446744073709551615\n[30] w 0x2109 0 r32 -0.1\n"
		"[31] w 0x210A 0 r64 1e-300\n[32] w 0x210B 0 t 1 86399999\n"
		"[33] w 0x210C 0 td 65535 0\n[34] w 0x210D 0 vs \"say \"\"hi\"\" # not a "
		"comment\"\n"
		"[35] w 0x210E 0 os AAEC/w==\n[36] w 0x210F 0 us SABpAA==\n"
		"[37] w 0x2110 0 d 3q2+7w==\n"
		"[38] r 0x2100 0 b\n[39] r 0x2101 0 i8\n[40] r 0x2102 0 i16\n"
		"[41] r 0x2103 0 i32\n[42] r 0x2104 0 i64\n[43] r 0x2105 0 u8\n"
		"[44] r 0x2106 0 u16\n[45] r 0x2107 0 u32\n[46] r 0x2108 0 u64\n"
		"[47] r 0x2109 0 r32\n[48] r 0x210A 0 r64\n[49] r 0x210B 0 t\n"
		"[50] r 0x210C 0 td\n[51] r 0x210D 0 vs\n[52] r 0x210E 0 os\n"
		"[53] r 0x210F 0 us\n[54] r 0x2110 0 d\n[55] r 0x2108 0 x64\n"
		"[56] w 0x2100 0 b 1\n[57] w 0x2101 0 x8 0xFB\n[58] w 0x2102 0 x16 0xFED4\n"
		"[59] w 0x2103 0 i32 -70000\n[60] w 0x2104 0 i64 -5000000000\n"
		"[61] w 0x2105 0 u8 200\n[62] w 0x2106 0 u16 60000\n[63] w 0x2107 0 x32 "
		"0xDEADBEEF\n"
		"[64] w 0x2108 0 x64 0x0123456789ABCDEF\n[65] w 0x2109 0 r32 1.5\n"
		"[66] w 0x210A 0 r64 -2.25\n[67] w 0x210B 0 t 14000 3600000\n"
		"[68] w 0x210C 0 td 2 1\n[69] w 0x210D 0 vs \"hello world\"\n"
		"[70] w 0x210E 0 hex 01 02 03\n[71] w 0x210F 0 us QQBCAA==\n"
		"[72] w 0x2110 0 hex DE AD\n",
		"OK\nOK\n"
		"[1] 1\n[2] -5\n[3] -300\n[4] -70000\n[5] -5000000000\n[6] 200\n[7] 60000\n"
		"[8] 3735928559\n[9] 81985529216486895\n[10] 1.5\n[11] -2.25\n"
		"[12] 14000 3600000\n[13] 2 1\n[14] \"hello world\"\n[15] AQID\n[16] QQBCAA==\n"
		"[17] 3q0=\n[18] 0xDEADBEEF\n[19] 01 02 03\n[20] 01 02 03\n"
		"[21] OK\n[22] OK\n[23] OK\n[24] OK\n[25] OK\n[26] OK\n[27] OK\n[28] OK\n"
		"[29] OK\n[30] OK\n[31] OK\n[32] OK\n[33] OK\n[34] OK\n[35] OK\n[36] OK\n"
		"[37] OK\n"
		"[38] 0\n[39] -128\n[40] 32767\n[41] -2147483648\n[42] 9223372036854775807\n"
		"[43] 127\n[44] 1\n[45] 4294967295\n[46] 18446744073709551615\n[47] -0.1\n"
		"[48] 1e-300\n[49] 1 86399999\n[50] 65535 0\n"
		"[51] \"say \"\"hi\"\" # not a comment\"\n[52] AAEC/w==\n[53] SABpAA==\n"
		"[54] 3q2+7w==\n[55] 0xFFFFFFFFFFFFFFFF\n"
		"[56] OK\n[57] OK\n[58] OK\n[59] OK\n[60] OK\n[61] OK\n[62] OK\n[63] OK\n"
		"[64] OK\n[65] OK\n[66] OK\n[67] OK\n[68] OK\n[69] OK\n[70] OK\n[71] OK\n"
		"[72] OK\n");
}

/* set, NMT for one node and all, info, help, comments, sequence numbers
 * optional, LF and CR LF both answered with CR LF, networks by number. */
static void test_commands_and_line_endings(void)
{
	transcript("commands",
		   "# a comment line is answered with an empty line\n"
		   "\n"
		   "[1] 1 set network 1\r\n"
		   "[2] set node 5 # trailing comment\r\n"
		   "[3] set sdo_timeout 300\n"
		   "[4] set sdo_block 1\n"
		   "[5] r 0x210D 0 vs\n"
		   "[6] set sdo_block 0\n"
		   "[7] preop\n"
		   "[8] 1 5 start\n"
		   "[9] 2 6 stop\n"
		   "[10] 2 6 preoperational\n"
		   "[11] 3 all start\n"
		   "[12] 3 0 preop\n"
		   "[13] 3 7 reset comm\n"
		   "r 0x1018 4 u32\n"
		   "[14] 2 6 r 0x1018 4 u32\n"
		   "[15] 3 7 r 0x1000 0 x32\n"
		   "[16] info version\n"
		   "[17] help datatype\n",
		   "\n\n[1] OK\r\n[2] OK\r\n[3] OK\n[4] OK\n[5] \"hello world\"\n[6] OK\n[7] OK\n"
		   "[8] OK\n[9] OK\n[10] OK\n[11] OK\n[12] OK\n[13] OK\n4242\n[14] 4242\n"
		   "[15] 0x00000309\n"
		   "[16] cogw-ascii 1.0 (CiA 309-3 DS 2.1 command set, docs/ascii.md)\n"
		   "b i8 i16 i32 i64 u8 u16 u32 u64 r32 r64: numbers (decimal, or 0x hex in)\n"
		   "t td: <days> <ms>; vs: \"text\" (\"\" for a quote)\n"
		   "os us d: base64 (RFC 2045); x8 x16 x32 x64 hex: non-standard hex forms\n"
		   "[17] OK\n");
}

static const char *wait_text(int fd, const char *text, int timeout_ms);

/* A client that behaves like CANopenNode's cocomm: it sends one line with
 * LF and reads until it sees CR LF, then sends the next. Comment and blank
 * lines too: that tool sends every line of its file or its stdin. The
 * answers, without their CR LF, "|"-joined into out. */
static void cocomm_like(const char *const *lines, size_t n, char *out, size_t cap)
{
	int fd = connect_unix();
	size_t o = 0;

	TEST_ASSERT_TRUE(fd >= 0);
	out[0] = '\0';
	for (size_t i = 0; i < n; i++) {
		char got[512], msg[600];

		send_text(fd, lines[i]);
		send_text(fd, "\n");
		snprintf(got, sizeof got, "%s", wait_text(fd, "\r\n", 15000));
		char *crlf = strstr(got, "\r\n");

		snprintf(msg, sizeof msg, "no answer ending in CR LF to \"%s\" (got \"%s\")",
			 lines[i], got);
		TEST_ASSERT_NOT_NULL_MESSAGE(crlf, msg);
		*crlf = '\0';
		o += (size_t)snprintf(out + o, cap - o, "%s|", got);
	}
	close(fd);
}

/* CANopenNode's cocomm sends LF and waits for CR LF, also after a comment
 * or a blank line of its script: each line gets its CR LF answer. */
static void test_cocomm_gets_crlf_answers(void)
{
	static const char *const script[] = {
		"# the identity of node 5", "",
		"[1] set network 1",        "[2] 5 r 0x1018 4 u32",
		"3 7 r 0x1000 0 x32",       "[3] 5 w 0x2105 0 u8 200",
		"[4] 5 r 0x6666 0 u8",      "  # an indented comment",
		"[5] 2 6 r 0x1018 4 u32",
	};
	char out[512];

	cocomm_like(script, sizeof script / sizeof script[0], out, sizeof out);
	TEST_ASSERT_EQUAL_STRING("||[1] OK|[2] 4242|0x00000309|[3] OK|[4] ERROR: 0x06020000||"
				 "[5] 4242|",
				 out);
}

/* The daemon's own node-ID (127 on every line) is an ordinary target: its
 * object dictionary is read and written through every network it is
 * attached to, as the reference gateway reads its own node. */
static void test_own_node_is_a_target(void)
{
	int fd = connect_unix();
	char cmd[128], was[64];

	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_STRING("[1] \"cogw\"", ask(fd, "[1] 1 127 r 0x1008 0 vs"));
	TEST_ASSERT_EQUAL_STRING("[2] \"cogw\"", ask(fd, "[2] 3 127 r 0x1008 0 vs"));
	snprintf(was, sizeof was, "%s", ask(fd, "2 127 r 0x1017 0 u16"));
	TEST_ASSERT_EQUAL_STRING("[3] OK", ask(fd, "[3] 2 127 w 0x1017 0 u16 700"));
	TEST_ASSERT_EQUAL_STRING("[4] 700", ask(fd, "[4] 2 127 r 0x1017 0 u16"));
	TEST_ASSERT_EQUAL_STRING("[5] ERROR: 0x06020000", ask(fd, "[5] 2 127 r 0x6666 0 u8"));
	TEST_ASSERT_EQUAL_STRING("[6] ERROR: 0x06010002", ask(fd, "[6] 1 127 w 0x1000 0 u32 1"));
	snprintf(cmd, sizeof cmd, "[7] 2 127 w 0x1017 0 u16 %s", was);
	TEST_ASSERT_EQUAL_STRING("[7] OK", ask(fd, cmd));
	close(fd);
}

/* Command words, sub-commands and type keywords in any case, as scripts
 * written for the reference gateway spell them. */
static void test_commands_in_any_case(void)
{
	transcript("case",
		   "[1] SET NETWORK 1\n"
		   "[2] 5 R 0X1018 4 U32\n"
		   "[3] 5 READ 0x1018 4 u32\n"
		   "[4] 5 Write 0x2105 0 U8 0XC8\n"
		   "[5] 1 5 Start\n"
		   "[6] 5 PREOP\n"
		   "[7] 3 7 Read 0x1000 0 X32\n"
		   "[8] Set Node 5\n"
		   "[9] R 0x2105 0 u8\n"
		   "[10] INFO VERSION\n",
		   "[1] OK\n[2] 4242\n[3] 4242\n[4] OK\n[5] OK\n[6] OK\n[7] 0x00000309\n"
		   "[8] OK\n[9] 200\n"
		   "[10] cogw-ascii 1.0 (CiA 309-3 DS 2.1 command set, docs/ascii.md)\n");
}

/* A device's visible string with a trailing NUL (a C string sent with its
 * terminator) and a CR LF inside: the answer is one line without them;
 * hex shows every byte. */
static void test_vs_answer_has_no_control_bytes(void)
{
	transcript("vs-nul",
		   "[1] 1 5 w 0x210D 0 hex 6E 55 4C 0D 0A 21 00\n"
		   "[2] 1 5 r 0x210D 0 vs\n"
		   "[3] 1 5 r 0x210D 0 hex\n",
		   "[1] OK\n[2] \"nUL!\"\n[3] 6E 55 4C 0D 0A 21 00\n");
	/* apart: a small write would pass the large reads queued before it */
	transcript("vs-restore", "[4] 1 5 w 0x210D 0 vs \"hello world\"\n", "[4] OK\n");
}

/* A line with a NUL byte is a syntax error, answered with its sequence
 * number like every other. */
static void test_sequence_echoed_on_a_nul_byte(void)
{
	static const char input[] = "[186] 5 r 0x1018\0 0 u8\n[187] 1 5 r 0x1018 4 u32\n";

	transcript_bytes(sock_path, "nul-seq", input, sizeof input - 1,
			 "[186] ERROR: 101\n[187] 4242\n");
}

/* Each error number that can be provoked, and SDO aborts as their code. */
static void test_error_numbers(void)
{
	transcript("errors",
		   "[1] 5 r 0x1000 0 u32\n" /* no network set yet */
		   "[2] set network 1\n"
		   "[3] r 0x1000 0 u32\n" /* no node set */
		   "[4] 5 r 0x6666 0 u8\n"
		   "[5] 5 w 0x1000 0 u32 1\n"
		   "[6] 5 r 0x1018 1 u8\n"
		   "[7] 5 w 0x2105 0 u16 1\n"
		   "[8] 5 fly\n"
		   "[9] 5 r 0x1018\n"
		   "[10] 5 w 0x2105 0 u8 256\n"
		   "[11] 128 5 r 0x1000 0\n"
		   "[12] 200 r 0x1000 0\n"
		   "[13] 4 5 start\n"
		   "[14] set sdo_timeout 100\n"
		   "[15] 9 r 0x1000 0 u32\n"
		   "[16] lss_allnodes\n"
		   "[17] lss_get_node\n"
		   "[18] 0 r 0x1000 0\n"
		   "\x01\x02\xff\n",
		   "[1] ERROR: 104\n[2] OK\n[3] ERROR: 105\n[4] ERROR: 0x06020000\n"
		   "[5] ERROR: 0x06010002\n[6] ERROR: 0x06070010\n[7] ERROR: 0x06070012\n"
		   "[8] ERROR: 100\n[9] ERROR: 101\n[10] ERROR: 101\n[11] ERROR: 106\n"
		   "[12] ERROR: 107\n[13] ERROR: 106\n[14] OK\n[15] ERROR: 0x05040000\n"
		   "[16] ERROR: 100\n[17] ERROR: 103\n[18] ERROR: 107\nERROR: 100\n");
}

static void test_lss_services(void)
{
	transcript("lss",
		   "[1] 1 lss_switch_sel 0x250 0x309 3 4242\n"
		   "[2] 1 lss_get_node\n"
		   "[3] 1 lss_inquire_addr 0\n"
		   "[4] 1 lss_inquire_addr 1\n"
		   "[5] 1 lss_inquire_addr 3\n"
		   "[6] 1 lss_set_node 5\n"
		   "[7] 1 lss_conf_bitrate 0 0\n"
		   "[8] 1 lss_store\n"
		   "[9] 1 lss_switch_glob 0\n"
		   "[10] 1 lss_ident_nonconf\n"
		   "[11] 1 _lss_fastscan 300\n"
		   "[12] 1 lss_set_node 0\n",
		   "[1] OK\n[2] 5\n[3] 0x00000250\n[4] 0x00000309\n[5] 0x00001092\n[6] OK\n"
		   "[7] OK\n[8] OK\n[9] OK\n[10] 0\n[11] ERROR: 103\n[12] ERROR: 107\n");
}

/* A network that is not one of the gateway's lines goes through the
 * daemon's routed SDO (docs/gateway.md): a second gateway that knows of
 * line 0 only (network 1) reaches node 6 of network 2 through line 0's
 * gateway, which routes it to line 1. NMT has no routed form: 106. */
static void test_routed_network(void)
{
	static const char one_line[] =
		"{\"version\": 1, \"mailbox\": {\"instance\": \"asc\"},"
		" \"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127,"
		" \"network_id\": 1}]}";
	char cfg[200], sock[108], log[200];

	snprintf(cfg, sizeof cfg, "%s/one-line.json", d.dir);
	snprintf(sock, sizeof sock, "%s/routed.sock", d.dir);
	snprintf(log, sizeof log, "%s/routed.log", d.dir);
	TEST_ASSERT_EQUAL_INT(0, write_text_file(cfg, one_line));
	const char *argv[] = {
		"build/san/bin/cogw-ascii", "--daemon-config", cfg, "--socket", sock, NULL
	};
	pid_t pid = proc_spawn(argv, log, NULL);

	TEST_ASSERT_TRUE(pid > 0);
	TEST_ASSERT_TRUE(file_wait_contains(log, "serving instance", 10000));
	transcript_at(sock, "routed",
		      "[1] set sdo_timeout 5000\n"
		      "[2] 2 6 r 0x1018 4 u32\n"
		      "[3] 2 6 w 0x2105 0 u8 7\n"
		      "[4] 2 6 r 0x2105 0 u8\n"
		      "[5] 2 6 w 0x2105 0 u8 200\n"
		      "[6] 2 6 r 0x210D 0 vs\n"
		      "[7] 2 6 start\n"
		      "[8] 9 1 r 0x1000 0 u32\n",
		      "[1] OK\n[2] 4242\n[3] OK\n[4] 7\n[5] OK\n[6] \"hello world\"\n"
		      "[7] ERROR: 106\n[8] ERROR: 0x0A000001\n");
	int st = proc_stop(pid, SIGTERM, 10000);

	TEST_ASSERT_TRUE_MESSAGE(WIFEXITED(st) && WEXITSTATUS(st) == 0,
				 "the second gateway did not exit cleanly");
}

/* 16 connections at once over the three networks, pipelined reads; every
 * answer comes to its own connection, in its order. */
static void test_sixteen_concurrent_connections(void)
{
	int fds[16];
	char cmd[128], want[64];

	for (int i = 0; i < 16; i++) {
		fds[i] = connect_unix();
		TEST_ASSERT_TRUE(fds[i] >= 0);
	}
	for (int round = 0; round < 10; round++) {
		for (int i = 0; i < 16; i++) {
			int net = 1 + i % 3;

			snprintf(cmd, sizeof cmd, "[%d] %d %d r 0x1018 4 u32\n", 1000 * i + round,
				 net, 4 + net);
			send_text(fds[i], cmd);
		}
	}
	for (int i = 0; i < 16; i++) {
		char *got = recv_lines(fds[i], 10, 30000);
		char *p = got;

		for (int round = 0; round < 10; round++) {
			snprintf(want, sizeof want, "[%d] 4242\r\n", 1000 * i + round);
			TEST_ASSERT_EQUAL_STRING_LEN_MESSAGE(want, p, strlen(want), got);
			p += strlen(want);
		}
		close(fds[i]);
	}
}

static char *big_domain(size_t n, size_t *b64_len)
{
	uint8_t *raw = malloc(n);
	char *text = malloc((n + 2) / 3 * 4 + 64);

	for (size_t i = 0; i < n; i++)
		raw[i] = (uint8_t)(i * 7 + (i >> 8));
	*b64_len = ascii_base64_encode(raw, n, text);
	free(raw);
	return text;
}

/* A 1 MiB domain written and read back through the gateway (block
 * transfer), byte for byte. */
static void test_one_mib_domain(void)
{
	size_t n = 1u << 20, b64;
	char *text = big_domain(n, &b64);
	int fd = connect_unix();
	char *line = malloc(b64 + 64);
	int hl = snprintf(line, 64, "[1] 1 5 w 0x2110 0 d ");

	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_STRING("[0] OK", ask(fd, "[0] set sdo_block 1"));
	memcpy(line + hl, text, b64);
	memcpy(line + hl + b64, "\n", 2);
	send_all(fd, line, (size_t)hl + b64 + 1);
	TEST_ASSERT_EQUAL_STRING("[1] OK\r\n", recv_lines(fd, 1, 120000));
	send_text(fd, "[2] 1 5 r 0x2110 0 d\n");
	char *got = recv_lines(fd, 1, 120000);

	TEST_ASSERT_EQUAL_INT(0, strncmp(got, "[2] ", 4));
	TEST_ASSERT_EQUAL_size_t(b64 + 6, strlen(got));
	TEST_ASSERT_EQUAL_MEMORY(text, got + 4, b64);
	TEST_ASSERT_EQUAL_STRING("[3] OK", ask(fd, "[3] 1 5 w 0x2110 0 hex DE AD"));
	close(fd);
	free(line);
	free(text);
}

/* A connection killed while its large read is under way: the other
 * connections go on, and the daemon's transfer slots all come back (four
 * large reads at once succeed afterwards, with four slots configured). */
static void test_connection_killed_mid_transfer(void)
{
	size_t n = 128u * 1024u, b64;
	char *text = big_domain(n, &b64);
	char *line = malloc(b64 + 64);
	int fd = connect_unix(), hl = snprintf(line, 64, "set sdo_block 1\n1 5 w 0x2110 0 d ");
	int fds[4];

	TEST_ASSERT_TRUE(fd >= 0);
	memcpy(line + hl, text, b64);
	line[hl + b64] = '\n';
	send_all(fd, line, (size_t)hl + b64 + 1);
	TEST_ASSERT_EQUAL_STRING("OK\r\nOK\r\n", recv_lines(fd, 2, 60000));
	close(fd);
	for (int k = 0; k < 3; k++) {
		fd = connect_unix();
		send_text(fd, "set network 1\nset node 5\nset sdo_block 1\nr 0x2110 0 d\n");
		sleep_ms(20u * (unsigned)k);
		close(fd); /* killed with the read under way */
	}
	for (int i = 0; i < 4; i++) {
		fds[i] = connect_unix();
		send_text(fds[i], "set sdo_block 1\n1 5 r 0x2110 0 d\n");
	}
	for (int i = 0; i < 4; i++) {
		char *got = recv_lines(fds[i], 2, 120000);

		TEST_ASSERT_EQUAL_size_t_MESSAGE(4 + b64 + 2, strlen(got), got);
		TEST_ASSERT_EQUAL_STRING_LEN("OK\r\n", got, 4);
		TEST_ASSERT_EQUAL_MEMORY(text, got + 4, b64);
		close(fds[i]);
	}
	free(line);
	free(text);
}

/* Read until text shows up (or timeout): the whole text received. */
static const char *wait_text(int fd, const char *text, int timeout_ms)
{
	static char acc[8192];
	size_t len = 0;
	uint64_t end = mono_ms() + (uint64_t)timeout_ms;

	acc[0] = '\0';
	while (!strstr(acc, text) && mono_ms() < end && len < sizeof acc - 1) {
		struct pollfd p = { .fd = fd, .events = POLLIN };

		if (poll(&p, 1, (int)(end - mono_ms())) <= 0)
			break;
		ssize_t k = recv(fd, acc + len, sizeof acc - 1 - len, 0);

		if (k <= 0)
			break;
		len += (size_t)k;
		acc[len] = '\0';
	}
	return acc;
}

/* Bad input: an overlong line, binary garbage, half a line then silence,
 * a peer that never reads, too many connections. Nobody else waits. */
static void test_bad_input_holds_up_nobody(void)
{
	int half = connect_unix(), lazy = connect_unix(), good = connect_unix(), over;
	size_t big = 2u * 1024u * 1024u + 100u, b64;
	char *junk = malloc(big + 1);
	char *text = big_domain(96u * 1024u, &b64);

	TEST_ASSERT_TRUE(half >= 0 && lazy >= 0 && good >= 0);
	/* the never-reading peer reads a 96 KiB domain of node 6 (network 2)
	 * again and again: its answers pile up, nobody else's do */
	int hl = snprintf(junk, 64, "set sdo_block 1\n[0] 2 6 w 0x2110 0 d ");

	memcpy(junk + hl, text, b64);
	junk[hl + b64] = '\n';
	send_all(good, junk, (size_t)hl + b64 + 1);
	TEST_ASSERT_EQUAL_STRING("OK\r\n[0] OK\r\n", recv_lines(good, 2, 120000));
	TEST_ASSERT_EQUAL_STRING("[0] OK", ask(good, "[0] set sdo_block 0"));
	send_text(half, "[1] 1 5 r 0x10"); /* and never the rest */
	/* never reads: pipelined reads of the 96 KiB domain until its unread
	 * answers pass max_output; then it is no longer read from */
	fcntl(lazy, F_SETFL, O_NONBLOCK);
	for (int i = 0; i < 100; i++)
		if (send(lazy, "2 6 r 0x2110 0 d\n", 17, MSG_NOSIGNAL) < 0)
			break;
	TEST_ASSERT_EQUAL_STRING("[1] 4242", ask(good, "[1] 1 5 r 0x1018 4 u32"));

	over = connect_unix();
	memset(junk, 'x', big);
	junk[big] = '\n';
	send_all(over, junk, big + 1);
	TEST_ASSERT_EQUAL_STRING("ERROR: 600\r\n", recv_lines(over, 1, 15000));
	TEST_ASSERT_EQUAL_STRING("[2] 4242", ask(over, "[2] 1 5 r 0x1018 4 u32"));
	send_all(over, "\x00\x13\x37\xfe\xff garbage\n", 15);
	TEST_ASSERT_EQUAL_STRING("ERROR: 101\r\n", recv_lines(over, 1, 10000));
	TEST_ASSERT_EQUAL_STRING("[3] 4242", ask(good, "[3] 1 5 r 0x1018 4 u32"));

	/* beyond max_connections: a clear line, then the close */
	int extra[MAX_CONNECTIONS];
	int n_extra = 0, refused = 0;

	for (int i = 0; i < MAX_CONNECTIONS; i++) {
		int fd = connect_unix();

		if (fd < 0)
			break;
		extra[n_extra++] = fd;
	}
	for (int i = 0; i < n_extra; i++) {
		struct pollfd p = { .fd = extra[i], .events = POLLIN };

		if (poll(&p, 1, 200) == 1) {
			char b[32] = "";

			if (recv(extra[i], b, sizeof b - 1, 0) > 0 &&
			    strcmp(b, "ERROR: 102\r\n") == 0)
				refused++;
		}
	}
	TEST_ASSERT_EQUAL_INT(4, refused); /* 4 + 24 - 4 open: 4 over the limit */
	for (int i = 0; i < n_extra; i++)
		close(extra[i]);
	TEST_ASSERT_EQUAL_STRING("[4] 4242", ask(good, "[4] 1 5 r 0x1018 4 u32"));
	TEST_ASSERT_EQUAL_STRING("[5] OK", ask(good, "[5] 1 5 w 0x2110 0 hex DE AD"));
	close(half);
	close(lazy);
	close(over);
	close(good);
	free(junk);
	free(text);
}

/* TCP peers have the configuration's role: read-only by default. */
static void test_tcp_is_read_only(void)
{
	int fd = connect_tcp();

	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_STRING("[1] 4242", ask(fd, "[1] 1 5 r 0x1018 4 u32"));
	TEST_ASSERT_EQUAL_STRING("[2] ERROR: 100", ask(fd, "[2] 1 5 w 0x2105 0 u8 1"));
	TEST_ASSERT_EQUAL_STRING("[3] ERROR: 100", ask(fd, "[3] 1 5 start"));
	TEST_ASSERT_EQUAL_STRING("[4] ERROR: 100", ask(fd, "[4] 1 lss_switch_glob 0"));
	close(fd);
}

/* A UNIX peer gets its own user's rights from the daemon's rules: uid
 * 65534 is "read" there. */
/* As uid 65534: the answers to a read and a write, "|"-joined, into out. */
static void ask_as_nobody(char *out, size_t cap)
{
	int pipefd[2];

	memset(out, 0, cap);
	TEST_ASSERT_EQUAL_INT(0, pipe(pipefd));
	pid_t pid = fork();

	if (pid == 0) {
		close(pipefd[0]);
		if (setgid(65534) || setuid(65534))
			_exit(3);
		int fd = connect_unix();

		if (fd < 0)
			_exit(4);
		/* no Unity assertion in the child: its failure would run the
		 * rest of the group a second time */
		static const char *const cmds[] = { "[1] 1 5 r 0x1018 4 u32\n",
						    "[2] 1 5 w 0x2105 0 u8 1\n" };

		for (int i = 0; i < 2; i++) {
			char *got;

			if (send(fd, cmds[i], strlen(cmds[i]), MSG_NOSIGNAL) < 0 && i > 0)
				break;
			got = recv_lines(fd, 1, 15000);
			got[strcspn(got, "\r\n")] = '\0';
			dprintf(pipefd[1], i ? "%s" : "%s|", got);
		}
		_exit(0);
	}
	close(pipefd[1]);
	int st;

	waitpid(pid, &st, 0);
	ssize_t k = read(pipefd[0], out, cap - 1);

	close(pipefd[0]);
	TEST_ASSERT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0);
	TEST_ASSERT_TRUE(k > 0);
}

/* A UNIX peer gets its own user's rights from the daemon's rules: uid
 * 65534 is "read" there; after the rules change and SIGHUP, "none". */
static void test_unix_peer_mapped_through_rules(void)
{
	char out[256];
	char *none = strdup(daemon_json);
	char *at = strstr(none, "\"access\": \"read\"");

	TEST_ASSERT_EQUAL_INT(0, chmod(sock_path, 0666)); /* only to let that user in */
	TEST_ASSERT_EQUAL_INT(0, chmod(d.dir, 0755));
	ask_as_nobody(out, sizeof out);
	TEST_ASSERT_EQUAL_STRING("[1] 4242|[2] ERROR: 100", out);

	TEST_ASSERT_NOT_NULL(at);
	memcpy(at, "\"access\": \"none\"", strlen("\"access\": \"none\""));
	TEST_ASSERT_EQUAL_INT(0, write_text_file(d.config_path, none));
	kill(gw_pid, SIGHUP);
	TEST_ASSERT_TRUE(file_wait_contains(gw_log, "access rules reloaded", 5000));
	ask_as_nobody(out, sizeof out);
	TEST_ASSERT_EQUAL_STRING("ERROR: 100|", out); /* refused at connect, closed */

	TEST_ASSERT_EQUAL_INT(0, write_text_file(d.config_path, daemon_json));
	kill(gw_pid, SIGHUP);
	free(none);
	chmod(sock_path, 0660);
}

/* Unsolicited lines: EMCY, boot-up, NMT state, heartbeat lost/started. */
static void test_events_on_request(void)
{
	int fd = connect_unix(), quiet = connect_unix();
	const char *got;

	TEST_ASSERT_EQUAL_STRING("[1] OK", ask(fd, "[1] events on emcy boot hb"));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sims[0], "emcy 0x8130 0x10", NULL, 0, 5000));
	got = wait_text(fd, "\n", 10000);
	TEST_ASSERT_EQUAL_STRING("1 5 EMCY 0x8130 0x11 0x0000000000\r\n", got);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sims[0], "emcy clear", NULL, 0, 5000));
	got = wait_text(fd, "\n", 10000);
	TEST_ASSERT_EQUAL_STRING_LEN("1 5 EMCY 0x0000 ", got, 16);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sims[0], "hb stop", NULL, 0, 5000));
	got = wait_text(fd, "1 5 ERROR: 203\r\n", 10000);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(got, "1 5 ERROR: 203\r\n"), got);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sims[0], "hb start", NULL, 0, 5000));
	got = wait_text(fd, "1 5 ERROR: 202\r\n", 10000);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(got, "1 5 ERROR: 202\r\n"), got);
	send_text(fd, "[2] 1 5 reset node\n");
	got = wait_text(fd, "1 5 ERROR: 205\r\n", 10000);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(got, "1 5 ERROR: 205\r\n"), got);
	TEST_ASSERT_EQUAL_STRING("[3] OK", ask(fd, "[3] events off emcy boot hb"));
	send_text(fd, "[4] events on nmt\n[5] 1 5 start\n");
	got = wait_text(fd, "1 5 NMT OPERATIONAL\r\n", 10000);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(got, "1 5 NMT OPERATIONAL\r\n"), got);
	send_text(fd, "[6] events off\n[7] 1 5 preop\n");
	wait_text(fd, "[7] OK\r\n", 10000);
	close(fd);
	/* the connection that asked for nothing got nothing */
	TEST_ASSERT_EQUAL_STRING("[9] 4242", ask(quiet, "[9] 1 5 r 0x1018 4 u32"));
	close(quiet);
}

/* cogwd restarted under a connected client: an error line while it is
 * away, then the same connection works again. */
/* Every thread of pid stopped (SIGSTOP is delivered asynchronously). */
static bool all_threads_stopped(pid_t pid)
{
	char path[64], stat[512];
	bool stopped = true;
	struct dirent *e;
	DIR *dir;

	snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
	dir = opendir(path);
	if (!dir)
		return false;
	while (stopped && (e = readdir(dir))) {
		if (e->d_name[0] == '.')
			continue;
		char file[384];
		FILE *f;

		snprintf(file, sizeof file, "%s/%s/stat", path, e->d_name);
		f = fopen(file, "r");
		/* "tid (comm) S ...": the state follows the last ')' */
		char *close_paren = f && fgets(stat, sizeof stat, f) ? strrchr(stat, ')') : NULL;

		stopped = close_paren && close_paren[1] == ' ' && close_paren[2] == 'T';
		if (f)
			fclose(f);
	}
	closedir(dir);
	return stopped;
}

/* A line whose command queue in the daemon is full (the daemon stopped,
 * another writer filled its queue) holds the gateway up nowhere: the
 * command keeps its place, local commands are answered meanwhile, and the
 * command goes out once the queue has room (docs/ascii.md "Known limits").
 * Stopped for longer than a blocking send's 2 s: a gateway that waited for
 * room would have given the command up. */
static void test_full_command_queue_holds_up_nobody(void)
{
	int fd = connect_unix(), other = connect_unix();
	char qname[MBX_QNAME_MAX];
	unsigned filled = 0;
	mqd_t q;

	TEST_ASSERT_EQUAL_STRING("[1] 4242", ask(fd, "[1] 1 5 r 0x1018 4 u32"));
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(qname, sizeof qname, "asc", 0));
	q = mq_open(qname, O_WRONLY | O_NONBLOCK);
	TEST_ASSERT_TRUE(q != (mqd_t)-1);
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGSTOP));
	for (int i = 0; i < 100 && !all_threads_stopped(d.pid); i++)
		sleep_ms(20);
	TEST_ASSERT_TRUE_MESSAGE(all_threads_stopped(d.pid), "cogwd did not stop");
	/* empty messages: the daemon refuses and counts each as malformed */
	while (mq_send(q, "", 0, 0) == 0)
		filled++;
	TEST_ASSERT_EQUAL_INT(EAGAIN, errno);
	TEST_ASSERT_TRUE(filled > 0);
	send_text(fd, "[2] 1 5 r 0x1018 4 u32\n");
	TEST_ASSERT_EQUAL_STRING_LEN("[3] cogw-ascii", ask(other, "[3] info version"), 14);
	TEST_ASSERT_EQUAL_STRING("", recv_lines(fd, 1, 3000));
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGCONT));
	char *got = recv_lines(fd, 1, 15000);

	got[strcspn(got, "\r\n")] = '\0';
	TEST_ASSERT_EQUAL_STRING("[2] 4242", got);
	mq_close(q);
	close(other);
	close(fd);
}

static void test_daemon_restart_under_a_client(void)
{
	int fd = connect_unix();
	const char *a;
	daemon_opts o = {
		.config_file = NULL, .config_json = daemon_json, .instance = "asc", .n_lines = 3
	};
	static daemon_run d2;

	TEST_ASSERT_EQUAL_STRING("[1] 4242", ask(fd, "[1] 1 5 r 0x1018 4 u32"));
	TEST_ASSERT_TRUE(daemon_stop(&d, 10000) >= 0);
	a = ask(fd, "[2] 1 5 r 0x1018 4 u32");
	TEST_ASSERT_EQUAL_STRING("[2] ERROR: 102", a);
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&d2, &o));
	int ok = 0;

	for (int i = 0; i < 50 && !ok; i++) {
		a = ask(fd, "[3] 1 5 r 0x1018 4 u32");
		ok = strcmp(a, "[3] 4242") == 0;
		if (!ok) {
			TEST_ASSERT_EQUAL_STRING_LEN("[3] ERROR: ", a, 11);
			sleep_ms(200);
		}
	}
	TEST_ASSERT_TRUE_MESSAGE(ok, "the connection did not work again after the restart");
	close(fd);
	/* the second daemon is the group's from here on */
	daemon_stop(&d2, 10000);
	daemon_cleanup(&d2);
}

void setUp(void) {}

/* a failed test_full_command_queue_holds_up_nobody must not leave the
 * group's daemon stopped */
void tearDown(void)
{
	if (d.pid > 0)
		kill(d.pid, SIGCONT);
}

int main(void)
{
	daemon_opts o = { .config_json = daemon_json, .instance = "asc", .n_lines = 3 };
	int rc;

	UNITY_BEGIN();
	if (daemon_start(&d, &o) != 0) {
		printf("test_ascii: cogwd did not start\n");
		return 1;
	}
	for (unsigned l = 0; l < 3; l++) {
		char dev[128];

		snprintf(dev, sizeof dev, "%s:%u", DEVICE, 5 + l);
		const char *devs[] = { dev, NULL };

		/* the VM is slow and shared: the devices wait as long as we do */
		const char *extra[] = { "--sdo-timeout", "5000", NULL };

		if (cosim_start(&sims[l], d.dir, l, devs, extra) != 0) {
			printf("test_ascii: cosim on vcan%u did not start\n", l);
			return 1;
		}
	}
	if (start_gateway() != 0) {
		proc_dump_log(gw_log, 20);
		printf("test_ascii: cogw-ascii did not start\n");
		return 1;
	}
	RUN_TEST(test_every_type_keyword_byte_exact);
	RUN_TEST(test_commands_and_line_endings);
	RUN_TEST(test_cocomm_gets_crlf_answers);
	RUN_TEST(test_own_node_is_a_target);
	RUN_TEST(test_commands_in_any_case);
	RUN_TEST(test_vs_answer_has_no_control_bytes);
	RUN_TEST(test_sequence_echoed_on_a_nul_byte);
	RUN_TEST(test_error_numbers);
	RUN_TEST(test_lss_services);
	RUN_TEST(test_sixteen_concurrent_connections);
	RUN_TEST(test_routed_network);
	RUN_TEST(test_one_mib_domain);
	RUN_TEST(test_connection_killed_mid_transfer);
	RUN_TEST(test_bad_input_holds_up_nobody);
	RUN_TEST(test_tcp_is_read_only);
	RUN_TEST(test_unix_peer_mapped_through_rules);
	RUN_TEST(test_events_on_request);
	RUN_TEST(test_full_command_queue_holds_up_nobody);
	RUN_TEST(test_daemon_restart_under_a_client);
	rc = stop_gateway();
	proc_dump_log(gw_log, 60);
	if (!(WIFEXITED(rc) && WEXITSTATUS(rc) == 0))
		printf("test_ascii: cogw-ascii exit status %d (a leak or a crash): FAIL\n", rc);
	for (unsigned l = 0; l < 3; l++)
		cosim_stop(&sims[l], 5000);
	daemon_cleanup(&d);
	rc = UNITY_END() || !(WIFEXITED(rc) && WEXITSTATUS(rc) == 0);
	return rc;
}
