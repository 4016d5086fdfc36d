/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the CiA 302-7 gateway of a real cogwd (release build) on
 * vcan0 + vcan1, a simulated device (cosim, node 5) on vcan1.
 *
 *   - PDO forwarding latency vcan0 -> vcan1 (an RPDO mapping B000h on line
 *     0, an event-driven TPDO mapping it on line 1; p50/p99 from the send
 *     on vcan0 to the reception on vcan1), against the kernel's own can-gw
 *     forwarding a frame vcan2 -> vcan3 in the same run: target <= 3x.
 *     For context, the smallest user-space relay (one process, read() then
 *     write()) over the same lines; the three are measured in interleaved
 *     rounds, and kernel timestamps split each into send / forward /
 *     delivery stages (notes);
 *   - the same by device object (gateway.forward): node 6's TPDO 186h on
 *     vcan0 (6000h:1, UNSIGNED32) forwarded to node 9's RPDO 209h on vcan1
 *     (6200h:1 alone), both mirrored by the daemon, in the same rounds,
 *     against can-gw and against the B000h path;
 *   - routed SDO: a 1 MiB block upload through the gateway (network
 *     indication on vcan0, relayed to vcan1) against the same upload made
 *     directly on vcan1 (target >= 80 %), and the expedited round trip
 *     routed against direct (target <= 2x). The requester is the core's own
 *     SDO client on a raw socket in this process, the same code both ways.
 *
 * COGW_BENCH_GW_ONLY=pdo stops after the forwarding figures, =sdo measures
 * only the expedited reads (more of them) (tuning).
 */
#include <dirent.h>
#include <errno.h>
#include <inttypes.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/co.h"
#include "core/sdo_client.h"
#include "gateway/convention.h"
#include "tests/bench/support/bench.h"
#include "tests/integration/support/sdo_req.h"

#define NODE 5
#define GW 127
#define BLOCK_INDEX 0x2F00
#define BLOCK_SIZE (1024u * 1024u)

static char instance[32];
static char tmpdir[128];

static uint8_t pattern(uint32_t i)
{
	return (uint8_t)(i * 131u + (i >> 11));
}

/* A device file with one PDO (comm 1800h: TPDO, 1400h: RPDO, COB-ID cob)
 * that maps obj:1 alone, an UNSIGNED32. */
static int write_one_object_eds(const char *path, uint16_t comm, uint16_t obj, unsigned cob)
{
	char t[2048];
	snprintf(t, sizeof t,
		 "[FileInfo]\nFileName=bench.eds\nEDSVersion=4.0\n"
		 "[DeviceInfo]\nVendorName=cogw bench\nProductName=one object\n"
		 "[MandatoryObjects]\nSupportedObjects=1\n1=0x1000\n"
		 "[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\n"
		 "AccessType=ro\nDefaultValue=0\nPDOMapping=0\n"
		 "[OptionalObjects]\nSupportedObjects=3\n1=0x%04X\n2=0x%04X\n3=0x%04X\n"
		 "[%04X]\nParameterName=PDO 1 communication\nObjectType=0x9\nSubNumber=3\n"
		 "[%04Xsub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
		 "DefaultValue=2\nPDOMapping=0\n"
		 "[%04Xsub1]\nParameterName=COB-ID\nObjectType=0x7\nDataType=0x0007\n"
		 "AccessType=rw\nDefaultValue=0x%03X\nPDOMapping=0\n"
		 "[%04Xsub2]\nParameterName=transmission type\nObjectType=0x7\n"
		 "DataType=0x0005\nAccessType=rw\nDefaultValue=254\nPDOMapping=0\n"
		 "[%04X]\nParameterName=PDO 1 mapping\nObjectType=0x9\nSubNumber=2\n"
		 "[%04Xsub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\nAccessType=rw\n"
		 "DefaultValue=1\nPDOMapping=0\n"
		 "[%04Xsub1]\nParameterName=entry 1\nObjectType=0x7\nDataType=0x0007\n"
		 "AccessType=rw\nDefaultValue=0x%04X0120\nPDOMapping=0\n"
		 "[%04X]\nParameterName=value\nObjectType=0x8\nSubNumber=2\n"
		 "[%04Xsub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
		 "DefaultValue=1\nPDOMapping=0\n"
		 "[%04Xsub1]\nParameterName=value 1\nObjectType=0x7\nDataType=0x0007\n"
		 "AccessType=rw\nDefaultValue=0\nPDOMapping=1\n",
		 comm, comm + 0x200, obj, comm, comm, comm, cob, comm, comm + 0x200, comm + 0x200,
		 comm + 0x200, obj, obj, obj, obj);
	return bench_write_file(path, t);
}

static int write_config(const char *path, const char *src_eds, const char *dst_eds)
{
	char text[4096];
	snprintf(text, sizeof text,
		 "{\"state_dir\": \"%s/state\", \"mailbox\": {\"instance\": \"%s\"},\n"
		 " \"gateway\": {\"process_image\": [{\"index\": \"0xB000\", \"type\": "
		 "\"UNSIGNED32\","
		 " \"access\": \"rw\", \"pdo\": true}],\n"
		 "  \"forward\": [{\"from\": {\"line\": 0, \"node\": 6, \"index\": \"0x6000\", "
		 "\"sub\": 1},\n"
		 "    \"to\": {\"line\": 1, \"node\": 9, \"index\": \"0x6200\", \"sub\": 1}}]},\n"
		 " \"lines\": [\n"
		 "  {\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "
		 "\"network_id\": 1,\n"
		 "   \"nodes\": [{\"id\": 6, \"eds\": \"%s\", \"pdo\": \"auto\"}],\n"
		 "   \"heartbeat_ms\": 0, \"sdo_timeout_ms\": 5000, \"rpdos\": 2, \"values\": [\n"
		 "    {\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x181\"},\n"
		 "    {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0xB0000020\"},\n"
		 "    {\"index\": \"0x1600\", \"sub\": 0, \"value\": 1}]},\n"
		 "  {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "
		 "\"network_id\": 2,\n"
		 "   \"nodes\": [{\"id\": 9, \"eds\": \"%s\", \"pdo\": \"auto\"}],\n"
		 "   \"heartbeat_ms\": 0, \"sdo_timeout_ms\": 5000, \"tpdos\": 2, \"values\": [\n"
		 "    {\"index\": \"0x1800\", \"sub\": 1, \"value\": \"0x1FF\"},\n"
		 "    {\"index\": \"0x1A00\", \"sub\": 1, \"value\": \"0xB0000020\"},\n"
		 "    {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1}]}]}\n",
		 tmpdir, instance, src_eds, dst_eds);
	return bench_write_file(path, text);
}

static int write_device(const char *path)
{
	char text[1024];
	snprintf(text, sizeof text,
		 "{\"name\": \"bench device\", \"node_id\": %d,\n"
		 " \"objects\": [{\"index\": \"0x%04X\", \"type\": \"DOMAIN\", \"access\": \"rw\","
		 " \"max_size\": %u}]}\n",
		 NODE, BLOCK_INDEX, BLOCK_SIZE);
	return bench_write_file(path, text);
}

static int open_filtered(const char *ifname, uint32_t id)
{
	int fd = can_open_raw(ifname);
	if (fd < 0)
		return fd;
	struct can_filter f = { .can_id = id,
				.can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG };
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f);
	return fd;
}

/* ---- forwarding latency: send a counter on one line, wait for it on another -------- */

static void drain(int fd)
{
	struct can_frame cf;
	struct pollfd p = { .fd = fd, .events = POLLIN };
	while (poll(&p, 1, 0) > 0 && read(fd, &cf, sizeof cf) > 0)
		;
}

/* Kernel receive timestamps (SO_TIMESTAMPNS, CLOCK_REALTIME) split the
 * latency into stages without touching the forwarder: the sending socket
 * also receives its own frame (CAN_RAW_RECV_OWN_MSGS), stamped when the
 * frame entered the source line; the receiving socket's stamp is when the
 * forwarded frame entered the target line. */
typedef struct fwd_stages {
	double *send;    /* bench send() -> frame on the source line */
	double *forward; /* source line -> forwarded frame on the target line */
	double *deliver; /* target line -> the bench holds the frame */
} fwd_stages;

static void stamp_socket(int fd, bool own)
{
	int on = 1;
	setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
	if (own)
		setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &on, sizeof on);
}

static uint64_t realtime_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* One frame with id within timeout_ms: its length, data and kernel stamp
 * (ns, 0 if none); -1 on timeout. */
static int recv_stamped(int fd, uint32_t id, uint8_t data[8], uint64_t *ts_ns, int timeout_ms)
{
	uint64_t until = bench_now_ns() + (uint64_t)timeout_ms * 1000000u;
	for (;;) {
		struct pollfd p = { .fd = fd, .events = POLLIN };
		uint64_t now = bench_now_ns();
		if (now >= until || poll(&p, 1, (int)((until - now) / 1000000u) + 1) <= 0)
			return -1;
		struct can_frame cf;
		char ctrl[CMSG_SPACE(sizeof(struct timespec))];
		struct iovec iov = { .iov_base = &cf, .iov_len = sizeof cf };
		struct msghdr mh = { .msg_iov = &iov,
				     .msg_iovlen = 1,
				     .msg_control = ctrl,
				     .msg_controllen = sizeof ctrl };
		if (recvmsg(fd, &mh, MSG_DONTWAIT) != (ssize_t)sizeof cf || cf.can_id != id)
			continue;
		*ts_ns = 0;
		for (struct cmsghdr *c = CMSG_FIRSTHDR(&mh); c; c = CMSG_NXTHDR(&mh, c))
			if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS) {
				struct timespec ts;
				memcpy(&ts, CMSG_DATA(c), sizeof ts);
				*ts_ns = (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
			}
		memcpy(data, cf.data, 8);
		return cf.len;
	}
}

/* Latencies in µs into v[] and, per measured frame, its stages; returns
 * the count measured. tx and rx are stamped sockets (stamp_socket). */
static size_t forward_latency(int tx, uint32_t tx_id, int rx, uint32_t rx_id, size_t n, double *v,
			      const fwd_stages *st)
{
	size_t got = 0;
	for (size_t i = 0; i < n; i++) {
		uint8_t d[8] = { 0 }, r[8], own[8];
		uint64_t in_ns = 0, out_ns = 0;
		co_put_le32(d, 0xC0DE0000u + (uint32_t)i);
		drain(rx);
		drain(tx);
		uint64_t t0_rt = realtime_ns(), t0 = bench_now_ns();
		if (can_send_std(tx, tx_id, d, 4) != 0)
			continue;
		for (;;) {
			int len = recv_stamped(rx, rx_id, r, &out_ns, 2000);
			if (len < 0)
				break;
			if (len == 4 && co_get_le32(r) == co_get_le32(d)) {
				uint64_t t1 = bench_now_ns(), t1_rt = realtime_ns();
				v[got] = (double)(t1 - t0) / 1000.0;
				/* our own frame back, read only now: not in the figure */
				if (recv_stamped(tx, tx_id, own, &in_ns, 100) == 4 && in_ns &&
				    out_ns) {
					st->send[got] = ((double)in_ns - (double)t0_rt) / 1000.0;
					st->forward[got] = ((double)out_ns - (double)in_ns) /
							   1000.0;
					st->deliver[got] = ((double)t1_rt - (double)out_ns) /
							   1000.0;
				} else {
					st->send[got] = st->forward[got] = st->deliver[got] = -1;
				}
				got++;
				break;
			}
		}
	}
	return got;
}

/* The stage medians of a latency run as one note. */
static void note_stages(const char *what, const fwd_stages *st, size_t n)
{
	size_t k = 0;
	for (size_t i = 0; i < n; i++)
		if (st->forward[i] >= 0) {
			st->send[k] = st->send[i];
			st->forward[k] = st->forward[i];
			st->deliver[k] = st->deliver[i];
			k++;
		}
	if (k == 0) {
		bench_note("%s: no kernel timestamps, stages not measured", what);
		return;
	}
	double s = bench_percentile(st->send, k, 50), f = bench_percentile(st->forward, k, 50),
	       d = bench_percentile(st->deliver, k, 50);
	double f99 = bench_percentile(st->forward, k, 99);
	bench_note("%s stages (kernel timestamps, median of %zu): send %.1f us, forward (source "
		   "line to target line) %.1f us (p99 %.1f us), delivery to the reader %.1f us",
		   what, k, s, f, f99, d);
}

/* A user-space relay as small as it gets: one process, one raw socket on
 * each line, read() then write(). What any forwarder outside the kernel
 * pays at least (one wake-up more than can-gw, which forwards inside the
 * sender's own send call); the gateway hands each value from one line
 * thread to the other on top of that. Returns the child or -1. */
static pid_t relay_start(const char *from, const char *to, uint32_t id)
{
	int ready[2];
	if (pipe(ready) != 0)
		return -1;
	pid_t pid = fork();
	if (pid == 0) {
		close(ready[0]);
		int in = open_filtered(from, id), out = can_open_raw(to);
		struct can_frame cf;
		if (in < 0 || out < 0)
			_exit(1);
		(void)!write(ready[1], "r", 1);
		close(ready[1]);
		for (;;)
			if (read(in, &cf, sizeof cf) == (ssize_t)sizeof cf)
				(void)!write(out, &cf, sizeof cf);
	}
	close(ready[1]);
	char c;
	bool ok = pid > 0 && read(ready[0], &c, 1) == 1;
	close(ready[0]);
	if (!ok && pid > 0) {
		kill(pid, SIGKILL);
		waitpid(pid, NULL, 0);
	}
	return ok ? pid : -1;
}

/* ---- the requester: a core SDO client on a raw socket (tests/integration/support) --- */

typedef struct requester {
	sdo_req sr;
	double indication_s; /* the last network indication's round trip */
} requester;

static int rq_open(requester *q, const char *ifname)
{
	int fd = can_open_raw(ifname), big = 4 * 1024 * 1024;

	q->sr.fd = fd;
	if (fd < 0)
		return -1;
	setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
	return sdo_req_init(&q->sr, fd, 1, 5000);
}

static void rq_close(requester *q)
{
	sdo_req_fini(&q->sr);
	if (q->sr.fd >= 0)
		close(q->sr.fd);
}

/* The network indication for (2, NODE) to the gateway; 0 when confirmed. */
static int indicate(requester *q)
{
	uint8_t d[8], a[8];
	gw_netind_encode(d, (gw_netind){ 2, NODE });
	drain(q->sr.fd);
	if (can_send_std(q->sr.fd, 0x600 + GW, d, 8) != 0 ||
	    can_wait_id(q->sr.fd, 0x580 + GW, a, 5000) != 8)
		return -1;
	return memcmp(a, d, 8) == 0 ? 0 : -1;
}

/* One SDO transfer; routed: after an indication, to the gateway. Seconds or -1. */
static double transfer(requester *q, bool routed, const sdo_client_req *r0)
{
	sdo_client_req r = *r0;
	r.node_id = routed ? GW : NODE;
	/* Each requester's raw socket hears its whole line while the other
	 * one works: the gateway's relay of a routed transfer to node 5 uses
	 * the same COB-IDs (605h/585h) as the direct requester on vcan1, so
	 * its frames wait there, and the first one would answer this
	 * transfer's initiate out of turn (05040001 from our own client). */
	drain(q->sr.fd);
	double t0 = bench_now_s();
	if (routed && indicate(q) < 0) {
		printf("bench_vcan_gateway: the gateway did not confirm the network indication\n");
		return -1;
	}
	q->indication_s = routed ? bench_now_s() - t0 : 0;
	int rc = sdo_req_transfer(&q->sr, &r, 300000);
	double took = bench_now_s() - t0;
	if (rc || q->sr.res.abort) {
		printf("bench_vcan_gateway: %s SDO %04X failed: abort %08X\n",
		       routed ? "routed" : "direct", r.index, rc ? 0 : q->sr.res.abort);
		return -1;
	}
	return took;
}

static double block_upload(requester *q, bool routed, uint8_t *buf)
{
	sdo_client_req r = { .upload = true,
			     .index = BLOCK_INDEX,
			     .mode = SDO_MODE_BLOCK,
			     .buf = buf,
			     .cap = BLOCK_SIZE,
			     .size = BLOCK_SIZE };
	memset(buf, 0, BLOCK_SIZE);
	double s = transfer(q, routed, &r);
	if (s < 0)
		return -1;
	for (uint32_t i = 0; i < BLOCK_SIZE; i++)
		if (buf[i] != pattern(i)) {
			printf("bench_vcan_gateway: byte %u of the upload is wrong\n", i);
			return -1;
		}
	return s;
}

/* Median expedited round trip in µs over n reads of 1000h; routed: also
 * the median of its network indication's round trip (*ind_us). */
static double expedited_us(requester *q, bool routed, int n, double *ind_us)
{
	double *v = calloc(2 * (size_t)n, sizeof *v), *ind = v ? v + n : NULL;
	uint8_t b[4];
	sdo_client_req r = { .upload = true, .index = 0x1000, .buf = b, .cap = 4 };
	int got = 0;
	for (int i = 0; i < n && v; i++) {
		double s = transfer(q, routed, &r);
		if (s < 0)
			break;
		ind[got] = q->indication_s * 1e6;
		v[got++] = s * 1e6;
	}
	double med = got ? bench_percentile(v, (size_t)got, 50) : -1;
	*ind_us = got ? bench_percentile(ind, (size_t)got, 50) : -1;
	free(v);
	return med;
}

/* Context switches (voluntary + not) of each thread of pid, by thread
 * name: the wake-ups a routed read costs the daemon (docs/fastpath.md). */
#define SWITCH_THREADS 16
typedef struct switches {
	int n;
	int tid[SWITCH_THREADS];
	char name[SWITCH_THREADS][16];
	uint64_t count[SWITCH_THREADS];
} switches;

static void switches_of(pid_t pid, switches *s)
{
	char dir[64];
	struct dirent *e;

	s->n = 0;
	snprintf(dir, sizeof dir, "/proc/%d/task", (int)pid);
	DIR *dp = opendir(dir);
	while (dp && (e = readdir(dp)) && s->n < SWITCH_THREADS) {
		char path[sizeof dir + sizeof e->d_name + 8], line[128];
		if (e->d_name[0] == '.')
			continue;
		snprintf(path, sizeof path, "%s/%s/status", dir, e->d_name);
		FILE *f = fopen(path, "r");
		if (!f)
			continue;
		s->tid[s->n] = atoi(e->d_name);
		uint64_t v = 0, sum = 0;
		s->name[s->n][0] = 0;
		while (fgets(line, sizeof line, f)) {
			if (sscanf(line, "Name: %15s", s->name[s->n]) == 1)
				continue;
			if (sscanf(line, "voluntary_ctxt_switches: %" SCNu64, &v) == 1 ||
			    sscanf(line, "nonvoluntary_ctxt_switches: %" SCNu64, &v) == 1)
				sum += v;
		}
		fclose(f);
		s->count[s->n++] = sum;
	}
	if (dp)
		closedir(dp);
}

/* "name a.b, ..." per read: (after - before) / reads, threads that moved. */
static void switches_note(const char *what, const switches *a, const switches *b, int reads)
{
	char text[512];
	size_t len = 0;
	double total = 0;

	text[0] = 0;
	for (int i = 0; i < a->n; i++) {
		int j = 0;
		while (j < b->n && b->tid[j] != a->tid[i])
			j++;
		if (j == b->n)
			continue;
		double per = (double)(b->count[j] - a->count[i]) / reads;
		total += per;
		if (per >= 0.05 && len < sizeof text - 40)
			len += (size_t)snprintf(text + len, sizeof text - len, "%s%s %.1f",
						len ? ", " : "", a->name[i], per);
	}
	bench_note("%s: cogwd's context switches per read %.1f (%s)", what, total, text);
}

/* The three forwarders of the latency figures, measured in interleaved
 * rounds so that the load of the machine (a shared host under the VM
 * moves the figures by several times within a minute) falls on all three
 * alike. */
enum {
	WAY_CANGW,
	WAY_RELAY,
	WAY_COGW,
	WAY_DEVOBJ,
	WAYS
};
#define LAT_ROUNDS 10

typedef struct way {
	const char *name;
	double *lat;
	fwd_stages st;
	size_t n;
	size_t round_end[LAT_ROUNDS]; /* n after each round: the spread over rounds */
} way;

/* Up to per_round more samples of one forwarder into w. */
static void way_measure(way *w, int tx, uint32_t tx_id, int rx, uint32_t rx_id, size_t per_round)
{
	fwd_stages at = { w->st.send + w->n, w->st.forward + w->n, w->st.deliver + w->n };
	w->n += forward_latency(tx, tx_id, rx, rx_id, per_round, w->lat + w->n, &at);
}

static void latency_rounds(way *ways, size_t per_round, const int fd[6])
{
	int tx0 = fd[0], rx1 = fd[1], tx2 = fd[2], rx3 = fd[3];

	for (int r = 0; r < LAT_ROUNDS; r++) {
		if (tx2 >= 0 && rx3 >= 0 &&
		    system("cangw -A -s vcan2 -d vcan3 -e >/dev/null 2>&1") == 0) {
			way_measure(&ways[WAY_CANGW], tx2, 0x181, rx3, 0x181, per_round);
			if (system("cangw -F >/dev/null 2>&1") != 0)
				bench_note("cangw -F failed");
		}
		pid_t relay = tx2 >= 0 && rx3 >= 0 ? relay_start("vcan2", "vcan3", 0x181) : -1;
		if (relay > 0) {
			way_measure(&ways[WAY_RELAY], tx2, 0x181, rx3, 0x181, per_round);
			kill(relay, SIGKILL);
			waitpid(relay, NULL, 0);
		}
		way_measure(&ways[WAY_COGW], tx0, 0x181, rx1, 0x1FF, per_round);
		if (fd[4] >= 0 && fd[5] >= 0)
			way_measure(&ways[WAY_DEVOBJ], fd[4], 0x186, fd[5], 0x209, per_round);
		for (int i = 0; i < WAYS; i++)
			ways[i].round_end[r] = ways[i].n;
	}
}

/* Percentile pct of the samples round r took of w (-1: none). */
static double round_percentile(const way *w, int r, int pct)
{
	size_t from = r ? w->round_end[r - 1] : 0, n = w->round_end[r] - from;
	double tmp[2000];

	if (n == 0 || n > sizeof tmp / sizeof tmp[0])
		return -1;
	memcpy(tmp, w->lat + from, n * sizeof tmp[0]);
	return bench_percentile(tmp, n, pct);
}

/* The gateway against the one-process relay, percentile pct: the figure
 * over all rounds, and the ratio's spread over the rounds as a note. */
static void relay_figure(const way *c, const way *u, int pct, double target)
{
	double v = bench_percentile(c->lat, c->n, pct), b = bench_percentile(u->lat, u->n, pct);
	double lo = -1, hi = -1;
	char name[96], base[96], tgt[32];

	for (int r = 0; r < LAT_ROUNDS; r++) {
		double cv = round_percentile(c, r, pct), uv = round_percentile(u, r, pct);
		if (cv < 0 || uv <= 0)
			continue;
		if (lo < 0 || cv / uv < lo)
			lo = cv / uv;
		if (hi < 0 || cv / uv > hi)
			hi = cv / uv;
	}
	snprintf(name, sizeof name, "PDO forwarding latency vcan0 to vcan1 against the relay, p%d",
		 pct);
	snprintf(base, sizeof base, "one-process relay vcan2 to vcan3, p%d", pct);
	snprintf(tgt, sizeof tgt, "ratio <= %.2f", target);
	bench_print_figure(&(bench_figure){ .name = name,
					    .value = v,
					    .unit = "us",
					    .base_name = base,
					    .base_value = b,
					    .base_unit = "us",
					    .ratio = b > 0 ? v / b : -1,
					    .target = tgt,
					    .verdict = bench_verdict(b > 0 && v <= target * b) });
	bench_note("PDO forwarding p%d against the relay, spread over the %d rounds (each about "
		   "%zu samples): %.2fx .. %.2fx",
		   pct, LAT_ROUNDS, c->n / LAT_ROUNDS, lo, hi);
}

/* One latency figure against the can-gw figure of the same percentile;
 * target NULL: context only. */
static void latency_figure(const char *name, double value, int pct, double cangw,
			   const char *target)
{
	char base[64];
	snprintf(base, sizeof base, "kernel can-gw vcan2 to vcan3, p%d", pct);
	bench_print_figure(&(bench_figure){
		.name = name,
		.value = value,
		.unit = "us",
		.base_name = base,
		.base_value = cangw,
		.base_unit = "us",
		.ratio = cangw > 0 ? value / cangw : -1,
		.target = target ? target : "none (context: the floor outside the kernel)",
		.verdict = target && cangw > 0 ? bench_verdict(value <= 3 * cangw) : "-" });
}

static void print_latency(way *ways, size_t asked)
{
	way *g = &ways[WAY_CANGW], *u = &ways[WAY_RELAY], *c = &ways[WAY_COGW];
	double gw_p50 = g->n ? bench_percentile(g->lat, g->n, 50) : -1,
	       gw_p99 = g->n ? bench_percentile(g->lat, g->n, 99) : -1;
	double p50 = bench_percentile(c->lat, c->n, 50), p99 = bench_percentile(c->lat, c->n, 99);

	if (gw_p50 < 0)
		bench_note(
			"kernel can-gw: not measured (needs cangw(8), root and the can-gw module)");
	latency_figure("PDO forwarding latency vcan0 to vcan1, p50", p50, 50, gw_p50,
		       "ratio <= 3.00");
	latency_figure("PDO forwarding latency vcan0 to vcan1, p99", p99, 99, gw_p99,
		       "ratio <= 3.00");
	if (u->n) {
		double relay_p50 = bench_percentile(u->lat, u->n, 50);
		latency_figure("one-process user-space relay vcan2 to vcan3 (read then write), p50",
			       relay_p50, 50, gw_p50, NULL);
		relay_figure(c, u, 50, 1.30);
		relay_figure(c, u, 99, 2.00);
		bench_note(
			"PDO forwarding p50 against the one-process relay: %.2fx (line 0's thread "
			"sends line 1's TPDO itself when the TPDO may go at once: one wake-up, "
			"like the relay; docs/gateway.md)",
			p50 / relay_p50);
	}
	bench_note("PDO forwarding: %zu of %zu RPDOs timed from the send on vcan0 to the TPDO on "
		   "vcan1 (RPDO -> B000h image -> line 1's TPDO sent by line 0's thread, or "
		   "through the ring by line 1's), in %d rounds interleaved "
		   "with the can-gw and relay baselines",
		   c->n, asked, LAT_ROUNDS);
	for (int i = 0; i < WAYS; i++)
		if (ways[i].n)
			note_stages(ways[i].name, &ways[i].st, ways[i].n);
}

/* Device object forwarding (gateway.forward) against can-gw and against
 * the B000h path of the same rounds. */
static void print_devobj_latency(const way *ways, size_t asked)
{
	const way *g = &ways[WAY_CANGW], *c = &ways[WAY_COGW], *o = &ways[WAY_DEVOBJ];
	double gw_p50 = g->n ? bench_percentile(g->lat, g->n, 50) : -1;
	double p50 = bench_percentile(o->lat, o->n, 50), b000 = bench_percentile(c->lat, c->n, 50);

	if (!o->n) {
		bench_note("device object forwarding: no forwarded frame arrived (of %zu)", asked);
		return;
	}
	latency_figure("device object forwarding latency vcan0 to vcan1 (gateway.forward), p50",
		       p50, 50, gw_p50, NULL);
	bench_print_figure(&(bench_figure){
		.name = "device object forwarding latency against the B000h path, p50",
		.value = p50,
		.unit = "us",
		.base_name = "PDO forwarding latency vcan0 to vcan1 (B000h), p50",
		.base_value = b000,
		.base_unit = "us",
		.ratio = b000 > 0 ? p50 / b000 : -1,
		.target = "ratio <= 1.30",
		.verdict = bench_verdict(b000 > 0 && p50 <= 1.30 * b000) });
	bench_note("device object forwarding: %zu of %zu TPDOs of node 6 (186h, 6000h:1 "
		   "UNSIGNED32) timed from the send on vcan0 to node 9's RPDO 209h on vcan1 "
		   "(mirror RPDO -> forward image BF00h -> the mirror's TPDO, sent by line 0's "
		   "thread when it may go at once, docs/gateway.md), in the same rounds",
		   o->n, asked);
}

/* Context for the figures: what one precise clock read costs here. Every
 * line thread reads the clock once per wake-up (timers and inhibit times
 * need it), the can-gw baseline never does; under emulation with the hpet
 * clock source each read is a system call and an emulated device access. */
static void note_clock_cost(void)
{
	char src[32] = "unknown";
	FILE *f = fopen("/sys/devices/system/clocksource/clocksource0/current_clocksource", "r");
	if (f) {
		if (fscanf(f, "%31s", src) != 1)
			snprintf(src, sizeof src, "unknown");
		fclose(f);
	}
	enum {
		READS = 2000
	};
	uint64_t t0 = bench_now_ns();
	for (int i = 0; i < READS - 1; i++)
		(void)bench_now_ns();
	double each_us = (double)(bench_now_ns() - t0) / READS / 1000.0;
	bench_note("clock_gettime(CLOCK_MONOTONIC) costs %.2f us here (clock source %s); a line "
		   "thread reads it once per wake-up",
		   each_us, src);
}

int main(void)
{
	if (bench_setup(instance, sizeof instance, "benchgw", tmpdir, sizeof tmpdir, "gw") < 0)
		return 1;
	char cfg[256], dev[256], log[256], simlog[256], prog[256];
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(dev, sizeof dev, "%s/device.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(simlog, sizeof simlog, "%s/cosim.log", tmpdir);
	size_t n_lat = bench_in_vm() ? 300 : 2000;
	double *lat_v = calloc(4 * WAYS * n_lat, sizeof *lat_v);
	way ways[WAYS] = { { .name = "kernel can-gw" },
			   { .name = "one-process user-space relay" },
			   { .name = "cogw gateway" },
			   { .name = "cogw device object forward" } };
	char src_eds[256], dst_eds[256];
	int tx6 = -1, rx9 = -1;
	snprintf(src_eds, sizeof src_eds, "%s/source.eds", tmpdir);
	snprintf(dst_eds, sizeof dst_eds, "%s/target.eds", tmpdir);
	for (int i = 0; i < WAYS && lat_v; i++) {
		double *base = lat_v + 4 * (size_t)i * n_lat;
		ways[i].lat = base;
		ways[i].st = (fwd_stages){ base + n_lat, base + 2 * n_lat, base + 3 * n_lat };
	}
	uint8_t *buf = malloc(BLOCK_SIZE);
	bench_daemon d = { .pid = -1 };
	pid_t sim = -1;
	requester q0 = { .sr.fd = -1 }, q1 = { .sr.fd = -1 };
	int tx0 = -1, rx1 = -1, tx2 = -1, rx3 = -1, status = 1;

	printf("bench_vcan_gateway: cogwd on vcan0 + vcan1, cosim (node %d) on vcan1\n", NODE);
	if (!lat_v || !buf || write_one_object_eds(src_eds, 0x1800, 0x6000, 0x186) < 0 ||
	    write_one_object_eds(dst_eds, 0x1400, 0x6200, 0x209) < 0 ||
	    write_config(cfg, src_eds, dst_eds) < 0 || write_device(dev) < 0)
		goto out;

	const char *sim_argv[] = { bench_program("cosim", prog, sizeof prog),
				   "--interface",
				   "vcan1",
				   "--device",
				   dev,
				   "--quiet",
				   NULL };
	if (bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	/* the baselines forward vcan2 -> vcan3, the gateway vcan0 -> vcan1 */
	tx0 = open_filtered("vcan0", 0x181);
	rx1 = open_filtered("vcan1", 0x1FF);
	tx2 = open_filtered("vcan2", 0x181);
	rx3 = open_filtered("vcan3", 0x181);
	tx6 = open_filtered("vcan0", 0x186);
	rx9 = open_filtered("vcan1", 0x209);
	stamp_socket(tx6, true);
	stamp_socket(rx9, false);
	stamp_socket(tx0, true);
	stamp_socket(rx1, false);
	stamp_socket(tx2, true);
	stamp_socket(rx3, false);
	if (tx0 < 0 || rx1 < 0 || rq_open(&q0, "vcan0") || rq_open(&q1, "vcan1"))
		goto out;
	/* the daemon's node OPERATIONAL on both lines (PDOs run only there) */
	uint8_t start[2] = { 0x01, GW };
	can_send_std(tx0, 0, start, 2);
	can_send_std(q1.sr.fd, 0, start, 2);
	sleep_ms(500);

	/* COGW_BENCH_GW_ONLY=pdo: the forwarding figures alone, =sdo: the
	 * expedited reads alone (while tuning) */
	const char *only = getenv("COGW_BENCH_GW_ONLY");
	bool sdo_only = only && strcmp(only, "sdo") == 0;

	/* Before the simulated device starts: on real lines the devices do not
	 * compete with the gateway for its processors, in the VM cosim would
	 * (it reads every frame of vcan1, the forwarded TPDO included). */
	if (!sdo_only) {
		latency_rounds(ways, n_lat / LAT_ROUNDS,
			       (const int[6]){ tx0, rx1, tx2, rx3, tx6, rx9 });
		if (ways[WAY_COGW].n == 0) {
			printf("bench_vcan_gateway: no forwarded PDO arrived\n");
			goto out;
		}
		print_latency(ways, n_lat);
		print_devobj_latency(ways, n_lat);
		note_clock_cost();
	}
	if (only && strcmp(only, "pdo") == 0) {
		status = 0;
		goto out;
	}
	sim = proc_spawn(sim_argv, simlog, NULL);
	uint8_t boot[8];
	if (can_wait_id(q1.sr.fd, 0x700 + NODE, boot, 10000) < 0)
		bench_note("cosim: no boot-up seen within 10 s");
	if (sdo_only) {
		/* the device answers before the reads are timed */
		uint8_t id[4];
		sdo_client_req r = { .upload = true, .index = 0x1000, .buf = id, .cap = 4 };
		for (uint64_t until = mono_ms() + 15000; transfer(&q1, false, &r) < 0;
		     sleep_ms(200))
			if (mono_ms() > until)
				goto out;
		goto expedited;
	}
	/* the device's domain holds the pattern: write it directly once */
	for (uint32_t i = 0; i < BLOCK_SIZE; i++)
		buf[i] = pattern(i);
	sdo_client_req w = {
		.index = BLOCK_INDEX, .mode = SDO_MODE_BLOCK, .data = buf, .size = BLOCK_SIZE
	};
	for (uint64_t until = mono_ms() + 15000; transfer(&q1, false, &w) < 0; sleep_ms(200))
		if (mono_ms() > until) {
			proc_dump_log(simlog, 10);
			goto out;
		}
	double direct = block_upload(&q1, false, buf), routed = block_upload(&q0, true, buf);
	if (direct < 0 || routed < 0)
		goto out;
	bench_print_figure(&(bench_figure){ .name = "routed SDO block upload 1 MiB (bytes/s)",
					    .value = BLOCK_SIZE / routed,
					    .unit = "B/s",
					    .base_name = "the same upload directly on vcan1",
					    .base_value = BLOCK_SIZE / direct,
					    .base_unit = "B/s",
					    .ratio = direct / routed,
					    .target = "ratio >= 0.80",
					    .verdict = bench_verdict(direct / routed >= 0.80) });
expedited:;
	int reps = bench_in_vm() ? (sdo_only ? 200 : 50) : 300;
	double ind_us, unused;
	switches sw0, sw1, sw2;
	switches_of(d.pid, &sw0);
	double ed = expedited_us(&q1, false, reps, &unused);
	switches_of(d.pid, &sw1);
	double er = expedited_us(&q0, true, reps, &ind_us);
	switches_of(d.pid, &sw2);
	switches_note("direct expedited read on vcan1 (cogwd's line 1 hears it)", &sw0, &sw1, reps);
	switches_note("routed expedited read", &sw1, &sw2, reps);
	if (ed < 0 || er < 0) {
		bench_note(
			"routed vs direct expedited SDO: not measured (a read failed, see above)");
		status = 0;
		goto out;
	}
	bench_print_figure(&(bench_figure){
		.name = "routed expedited SDO read (indication + transfer), median",
		.value = er,
		.unit = "us",
		.base_name = "the same read directly on vcan1",
		.base_value = ed,
		.base_unit = "us",
		.ratio = er / ed,
		.target = "ratio <= 2.00",
		.verdict = bench_verdict(er <= 2 * ed) });
	bench_note("routed SDO: the core's SDO client on a raw socket, on vcan0 through the "
		   "gateway (network indication first) or on vcan1 directly; %d expedited reads "
		   "each way, uploads checked byte for byte; of the routed read's median, the "
		   "network indication's round trip is %.0f us (the gateway confirms it at once "
		   "from the target line's lending board, docs/gateway.md)",
		   reps, ind_us);
	status = 0;
out:
	rq_close(&q0);
	rq_close(&q1);
	if (tx0 >= 0)
		close(tx0);
	if (rx1 >= 0)
		close(rx1);
	if (tx2 >= 0)
		close(tx2);
	if (rx3 >= 0)
		close(rx3);
	if (tx6 >= 0)
		close(tx6);
	if (rx9 >= 0)
		close(rx9);
	bench_daemon_stop(&d);
	if (sim > 0)
		proc_stop(sim, SIGTERM, 5000);
	bench_unlink_instance_queues(instance);
	bench_tmpdir_remove(tmpdir);
	free(lat_v);
	free(buf);
	return status;
}
