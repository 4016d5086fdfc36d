/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the MQTT bridge (cogw-mqtt, docs/mqtt.md) through a real cogwd
 * on vcan0 and a real mosquitto on loopback, against the broker alone, in
 * the same run:
 *
 *   - a device event on the bus (an EMCY frame of node 5 written to vcan0)
 *     until its message reaches an MQTT subscriber, p50 and p99, against a
 *     publish by a plain libmosquitto client (what mosquitto_pub is) until
 *     the same subscriber has it (target: p50 <= 2x);
 *   - EMCYs at a sustained rate through one bridge: delivered / sent and the
 *     bridge's CPU time per second of one core;
 *   - process values: 16 mirrored slaves (nodes 1..16, pdo "auto", one EDS
 *     written here) with 4 event-driven TPDOs each fill the bus with 9,000
 *     frames/s; the bridge watches one object of each TPDO (64 watches, the
 *     most its configuration takes) with a minimum interval of 100 ms: the
 *     values published per watch and second (10 at most, ideally 10) and the
 *     bridge's CPU (target: <= 20 % of one core, natively).
 *
 * Both clients use QoS 1, as the bridge does by default. Needs vcan0, the
 * release cogwd and cogw-mqtt and the mosquitto package: run through
 * tests/bench/run-vcan (make bench). Prints figures; asserts nothing.
 */
#include <mosquitto.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>

#include "tests/bench/support/bench.h"

#define PORT 18890
#define NODE 5
#define SAMPLES 200
#define TOPIC_EVENT "cogw/bench/net/1/node/5/emcy"
#define TOPIC_BASE "bench/baseline"
#define TOPIC_VALUES "cogw/bench/net/1/node/+/value/#"
#define PV_NODES 16
#define PV_TPDOS 4
#define PV_RATE 9000.0 /* frames/s: a full 1 Mbit/s bus of 8-byte PDOs */
#define PV_INTERVAL_MS 100

static char instance[32], tmpdir[64];

/* What the subscriber saw last: the code it carried and when. */
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t seen_cond = PTHREAD_COND_INITIALIZER;
static unsigned last_code;
static uint64_t last_ns, received, values_received;

static void on_message(struct mosquitto *m, void *obj, const struct mosquitto_message *msg)
{
	unsigned code = 0;
	const char *p;
	char text[512];
	size_t n = (size_t)msg->payloadlen < sizeof text - 1 ? (size_t)msg->payloadlen
							     : sizeof text - 1;

	(void)m;
	(void)obj;
	if (strstr(msg->topic, "/value/")) {
		pthread_mutex_lock(&lock);
		values_received++;
		pthread_mutex_unlock(&lock);
		return;
	}
	memcpy(text, msg->payload, n);
	text[n] = 0;
	p = strstr(text, "\"code\":\"0x");
	if (p)
		code = (unsigned)strtoul(p + 10, NULL, 16);
	pthread_mutex_lock(&lock);
	last_code = code;
	last_ns = bench_now_ns();
	received++;
	pthread_cond_broadcast(&seen_cond);
	pthread_mutex_unlock(&lock);
}

/* Wait until code was seen (up to 3 s); its arrival time, 0 if never. */
static uint64_t wait_code(unsigned code)
{
	struct timespec dl;
	uint64_t t = 0;

	clock_gettime(CLOCK_REALTIME, &dl);
	dl.tv_sec += 3;
	pthread_mutex_lock(&lock);
	while (last_code != code)
		if (pthread_cond_timedwait(&seen_cond, &lock, &dl))
			break;
	if (last_code == code)
		t = last_ns;
	pthread_mutex_unlock(&lock);
	return t;
}

static int can_open(const char *ifname)
{
	struct sockaddr_can a = { .can_family = AF_CAN };
	struct ifreq ifr;
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);

	snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
	if (fd < 0 || ioctl(fd, SIOCGIFINDEX, &ifr) < 0)
		return -1;
	a.can_ifindex = ifr.ifr_ifindex;
	return bind(fd, (struct sockaddr *)&a, sizeof a) < 0 ? -1 : fd;
}

static int send_emcy(int fd, unsigned code)
{
	struct can_frame f = { .can_id = 0x80 + NODE, .can_dlc = 8 };

	f.data[0] = (uint8_t)code;
	f.data[1] = (uint8_t)(code >> 8);
	f.data[2] = 0x01;
	return write(fd, &f, sizeof f) == sizeof f ? 0 : -1;
}

static struct mosquitto *client(const char *id, bool subscriber)
{
	struct mosquitto *m = mosquitto_new(id, true, NULL);

	if (!m)
		return NULL;
	if (subscriber)
		mosquitto_message_callback_set(m, on_message);
	if (mosquitto_connect(m, "127.0.0.1", PORT, 30) != MOSQ_ERR_SUCCESS ||
	    mosquitto_loop_start(m) != MOSQ_ERR_SUCCESS) {
		mosquitto_destroy(m);
		return NULL;
	}
	return m;
}

/* The broker's path: proc_spawn runs a path, not a name (Debian puts
 * mosquitto in /usr/sbin, which a user's PATH may lack). */
static const char *broker_path(char *buf, size_t n)
{
	const char *path = getenv("PATH");
	char dirs[4096];

	snprintf(dirs, sizeof dirs, "%s:/usr/sbin:/usr/local/sbin", path ? path : "/usr/bin");
	for (char *save = NULL, *d = strtok_r(dirs, ":", &save); d;
	     d = strtok_r(NULL, ":", &save)) {
		snprintf(buf, n, "%s/mosquitto", d);
		if (access(buf, X_OK) == 0)
			return buf;
	}
	return "mosquitto";
}

static int write_configs(char *cfg, char *bridge_cfg, char *broker_cfg, size_t n)
{
	char text[16384], eds[256];
	size_t k = 0;

	snprintf(cfg, n, "%s/cogw.json", tmpdir);
	snprintf(bridge_cfg, n, "%s/cogw-mqtt.json", tmpdir);
	snprintf(broker_cfg, n, "%s/mosquitto.conf", tmpdir);
	snprintf(eds, sizeof eds, "%s/slave.eds", tmpdir);
	if (bench_write_tpdo_eds(eds, PV_TPDOS) < 0)
		return -1;
	k += (size_t)snprintf(
		text + k, sizeof text - k,
		"{\"version\": 1, \"state_dir\": \"%s\", \"mailbox\": {\"instance\": "
		"\"%s\"},"
		" \"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 1000000, "
		"\"node_id\": 127, \"network_id\": 1, \"pdo\": \"auto\", \"rpdos\": %d,"
		" \"nodes\": [",
		tmpdir, instance, PV_NODES * PV_TPDOS);
	for (int id = 1; id <= PV_NODES; id++)
		k += (size_t)snprintf(text + k, sizeof text - k, "%s{\"id\": %d, \"eds\": \"%s\"}",
				      id > 1 ? ", " : "", id, eds);
	k += (size_t)snprintf(text + k, sizeof text - k, "]}]}");
	if (k >= sizeof text || bench_write_file(cfg, text) < 0)
		return -1;
	k = 0;
	k += (size_t)snprintf(text + k, sizeof text - k,
			      "{\"version\": 1, \"daemon_config\": \"%s\", \"gateway\": \"bench\","
			      " \"broker\": {\"uri\": \"mqtt://127.0.0.1:%d\"},"
			      " \"publish\": {\"counters_period_s\": 0, \"emcy_history\": 0},"
			      " \"queue\": {\"max_messages\": 100000, \"max_bytes\": 67108864},"
			      " \"watch\": [",
			      cfg, PORT);
	for (int id = 1; id <= PV_NODES; id++)
		for (int p = 0; p < PV_TPDOS; p++)
			k += (size_t)snprintf(
				text + k, sizeof text - k,
				"%s{\"net\": 1, \"node\": %d, \"index\": \"0x6401\", "
				"\"sub\": %d, \"type\": \"i16\", \"min_interval_ms\": %d}",
				id + p > 1 ? ", " : "", id, 4 * p + 1, PV_INTERVAL_MS);
	k += (size_t)snprintf(text + k, sizeof text - k, "]}");
	if (k >= sizeof text || bench_write_file(bridge_cfg, text) < 0)
		return -1;
	snprintf(text, sizeof text,
		 "%slistener %d 127.0.0.1\nallow_anonymous true\n"
		 "persistence false\nmax_queued_messages 100000\n",
		 getuid() == 0 ? "user root\n" : "", PORT);
	return bench_write_file(broker_cfg, text);
}

/* The mirrored slaves' TPDOs at PV_RATE frames/s for `secs` (1 ms steps,
 * round robin, values counting up): the values published per watch and
 * second, and the bridge's CPU share of one core. */
static void process_values(int fd, pid_t bridge, double secs, double *per_watch, double *cpu,
			   double *frames_s)
{
	uint8_t start[2] = { 0x01, 127 }; /* the daemon's node OPERATIONAL: RPDOs are used */
	struct can_frame f = { .can_dlc = 2 };
	memcpy(f.data, start, 2);
	f.can_id = 0;
	(void)!write(fd, &f, sizeof f);
	usleep(300000);
	uint64_t before, sent = 0;
	pthread_mutex_lock(&lock);
	before = values_received;
	pthread_mutex_unlock(&lock);
	double c0 = bench_process_cpu_s(bridge), t0 = bench_now_s(), t;
	while ((t = bench_now_s() - t0) < secs) {
		while ((double)sent < t * PV_RATE) {
			unsigned k = (unsigned)(sent % (PV_NODES * PV_TPDOS));
			struct can_frame pdo = { .can_id = 0x180u + 0x100u * (k % PV_TPDOS) + 1u +
							   k / PV_TPDOS,
						 .can_dlc = 8 };
			for (int e = 0; e < 4; e++) {
				pdo.data[2 * e] = (uint8_t)(sent >> 6);
				pdo.data[2 * e + 1] = (uint8_t)(sent >> 14);
			}
			if (write(fd, &pdo, sizeof pdo) == (ssize_t)sizeof pdo)
				sent++;
			else
				usleep(100); /* the vcan queue is full: the bus's own limit */
		}
		usleep(1000);
	}
	double wall = bench_now_s() - t0;
	*cpu = (bench_process_cpu_s(bridge) - c0) / wall;
	*frames_s = (double)sent / wall;
	usleep(500000); /* the last interval's values */
	pthread_mutex_lock(&lock);
	*per_watch = (double)(values_received - before) / (PV_NODES * PV_TPDOS) / wall;
	pthread_mutex_unlock(&lock);
}

/* EMCYs at `rate` per second for `secs`: delivered fraction and the
 * bridge's CPU share of one core. */
static void sustained(int fd, pid_t bridge, double rate, double secs, double *delivered,
		      double *cpu)
{
	uint64_t before, sent = 0;
	double c0 = bench_process_cpu_s(bridge), t0 = bench_now_s(), t;

	pthread_mutex_lock(&lock);
	before = received;
	pthread_mutex_unlock(&lock);
	while ((t = bench_now_s() - t0) < secs) {
		while ((double)sent < t * rate) {
			if (send_emcy(fd, 0x1000u + (unsigned)(sent & 0xFFF)) == 0)
				sent++;
			else
				usleep(100); /* the vcan queue is full: the bus's own limit */
		}
		usleep(500);
	}
	*cpu = (bench_process_cpu_s(bridge) - c0) / (bench_now_s() - t0);
	usleep(2000000); /* what is under way arrives */
	pthread_mutex_lock(&lock);
	*delivered = sent ? (double)(received - before) / (double)sent : 0;
	pthread_mutex_unlock(&lock);
}

int main(void)
{
	char cfg[256], bridge_cfg[256], broker_cfg[256], log[256], blog[256], mlog[256];
	char prog[256], broker_prog[300];
	static double ev[SAMPLES], base[SAMPLES];
	bench_daemon d = { .pid = -1 };
	pid_t broker = -1, bridge = -1;
	struct mosquitto *sub = NULL, *pub = NULL;
	int fd = -1, status = 1;
	size_t n_ev = 0, n_base = 0;

	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "mqtt") < 0)
		return 1;
	printf("bench_vcan_mqtt: cogwd on vcan0 + cogw-mqtt + mosquitto on loopback, %d samples\n",
	       SAMPLES);
	mosquitto_lib_init();
	if (write_configs(cfg, bridge_cfg, broker_cfg, sizeof cfg) < 0)
		goto out;
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(blog, sizeof blog, "%s/cogw-mqtt.log", tmpdir);
	snprintf(mlog, sizeof mlog, "%s/mosquitto.log", tmpdir);
	const char *broker_argv[] = { broker_path(broker_prog, sizeof broker_prog), "-c",
				      broker_cfg, NULL };

	broker = proc_spawn(broker_argv, mlog, NULL);
	if (broker <= 0 || !file_wait_contains(mlog, "running", 10000)) {
		printf("bench_vcan_mqtt: mosquitto did not start (make deps installs it)\n");
		goto out;
	}
	if (bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	sub = client("bench-sub", true);
	pub = client("bench-pub", false);
	if (!sub || !pub) {
		printf("bench_vcan_mqtt: cannot connect to mosquitto\n");
		goto out;
	}
	mosquitto_subscribe(sub, NULL, TOPIC_EVENT, 1);
	mosquitto_subscribe(sub, NULL, TOPIC_BASE, 1);
	mosquitto_subscribe(sub, NULL, TOPIC_VALUES, 1);
	const char *bridge_argv[] = { bench_program("cogw-mqtt", prog, sizeof prog), "--config",
				      bridge_cfg, NULL };

	bridge = proc_spawn(bridge_argv, blog, NULL);
	if (bridge <= 0 || !file_wait_contains(blog, "connected to", 10000)) {
		printf("bench_vcan_mqtt: cogw-mqtt did not connect\n");
		goto out;
	}
	fd = can_open("vcan0");
	if (fd < 0)
		goto out;
	usleep(1000000); /* the bridge's subscriptions to the daemon's events */
	for (unsigned i = 0; i < SAMPLES; i++) {
		unsigned code = 0x8000u + i;
		char payload[64];
		uint64_t t0 = bench_now_ns(), t;

		if (send_emcy(fd, code) == 0 && (t = wait_code(code)))
			ev[n_ev++] = (double)(t - t0) / 1e3;
		code = 0x9000u + i;
		snprintf(payload, sizeof payload, "{\"code\":\"0x%04X\"}", code);
		t0 = bench_now_ns();
		if (mosquitto_publish(pub, NULL, TOPIC_BASE, (int)strlen(payload), payload, 1,
				      false) == MOSQ_ERR_SUCCESS &&
		    (t = wait_code(code)))
			base[n_base++] = (double)(t - t0) / 1e3;
	}
	if (n_ev < SAMPLES / 2 || n_base < SAMPLES / 2) {
		printf("bench_vcan_mqtt: only %zu events and %zu publishes arrived of %d\n", n_ev,
		       n_base, SAMPLES);
		goto out;
	}
	double ev50 = bench_percentile(ev, n_ev, 50), base50 = bench_percentile(base, n_base, 50);
	double ev99 = bench_percentile(ev, n_ev, 99), base99 = bench_percentile(base, n_base, 99);

	bench_print_figure(
		&(bench_figure){ .name = "bus EMCY -> MQTT subscriber via cogw-mqtt, p50",
				 .value = ev50,
				 .unit = "us",
				 .base_name = "libmosquitto publish -> subscriber p50",
				 .base_value = base50,
				 .base_unit = "us",
				 .ratio = ev50 / base50,
				 .target = "ratio <= 2.00",
				 .verdict = bench_verdict(ev50 / base50 <= 2.0) });
	bench_print_figure(
		&(bench_figure){ .name = "bus EMCY -> MQTT subscriber via cogw-mqtt, p99",
				 .value = ev99,
				 .unit = "us",
				 .base_name = "libmosquitto publish -> subscriber p99",
				 .base_value = base99,
				 .base_unit = "us",
				 .ratio = ev99 / base99,
				 .target = "none (context)",
				 .verdict = "-" });
	double delivered, cpu, rate = bench_in_vm() ? 500 : 2000;

	sustained(fd, bridge, rate, 3.0, &delivered, &cpu);
	bench_print_figure(&(bench_figure){ .name = "EMCYs through cogw-mqtt delivered",
					    .value = 100.0 * delivered,
					    .unit = "%",
					    .base_name = "sent per second",
					    .base_value = rate,
					    .base_unit = "/s",
					    .ratio = -1,
					    .target = "100 % (no loss)",
					    .verdict = bench_verdict(delivered >= 0.999) });
	bench_print_figure(&(bench_figure){ .name = "cogw-mqtt CPU at that rate",
					    .value = 100.0 * cpu,
					    .unit = "% of a core",
					    .base_name = NULL,
					    .ratio = -1,
					    .target = "<= 20 %",
					    .verdict = bench_verdict(cpu <= 0.20) });
	double per_watch, pv_cpu, frames_s;

	process_values(fd, bridge, 3.0, &per_watch, &pv_cpu, &frames_s);
	char pv_name[160];
	snprintf(pv_name, sizeof pv_name,
		 "process values published per watch and second, 64 watches at %d ms, "
		 "%.0f PDO frames/s on the bus",
		 PV_INTERVAL_MS, frames_s);
	bench_print_figure(&(bench_figure){
		.name = pv_name,
		.value = per_watch,
		.unit = "/s",
		.base_name = "what the minimum interval lets through",
		.base_value = 1000.0 / PV_INTERVAL_MS,
		.base_unit = "/s",
		.ratio = per_watch / (1000.0 / PV_INTERVAL_MS),
		.target = "ratio >= 0.95",
		.verdict = bench_verdict(per_watch >= 0.95 * 1000.0 / PV_INTERVAL_MS) });
	bench_print_figure(&(bench_figure){ .name = "cogw-mqtt CPU with those process values",
					    .value = 100.0 * pv_cpu,
					    .unit = "% of a core",
					    .base_name = NULL,
					    .ratio = -1,
					    .target = "<= 20 %",
					    .verdict = bench_verdict(pv_cpu <= 0.20) });
	bench_note("cogw-mqtt: event latency is the bus frame written until the subscriber has the "
		   "message (daemon, mailbox, bridge, broker); the baseline is the broker alone");
	status = 0;
out:
	if (fd >= 0)
		close(fd);
	if (sub) {
		mosquitto_loop_stop(sub, true);
		mosquitto_destroy(sub);
	}
	if (pub) {
		mosquitto_loop_stop(pub, true);
		mosquitto_destroy(pub);
	}
	if (bridge > 0)
		proc_stop(bridge, SIGTERM, 5000);
	bench_daemon_stop(&d);
	if (broker > 0)
		proc_stop(broker, SIGTERM, 5000);
	mosquitto_lib_cleanup();
	if (getenv("COGW_BENCH_KEEP"))
		printf("bench_vcan_mqtt: logs kept in %s\n", tmpdir);
	else
		bench_tmpdir_remove(tmpdir);
	return status;
}
