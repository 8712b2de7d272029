/* v4l2-stream.c - kernel lane self-test: every vivid capture node streams at once, through
 * libv4l2 with mmap buffers, and each delivers frames with data and strictly increasing
 * timestamps and sequence numbers. The seed of gonio's V4L2 camera backend.
 *
 * Usage: kl-v4l2-stream [NODE...] (default: every /dev/video* whose driver is vivid; at least
 * two are required, the lane loads two vivid instances). */
#include <fcntl.h>
#include <glob.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <stdbool.h>
#include <sys/mman.h>
#include <time.h>

#include "common/cleanup.h"
#include "tests/test.h"

#define MAX_NODES 8
#define N_BUFS    4
#define N_FRAMES  10

struct node {
        const char *path;
        int fd;
        void *buf[N_BUFS];
        size_t len[N_BUFS];
        unsigned frames;
        unsigned long long last_us;
        unsigned last_seq;
};

static int xioctl(int fd, unsigned long req, void *arg)
{
        int r;

        do
                r = v4l2_ioctl(fd, req, arg);
        while (r < 0 && errno == EINTR);
        return r < 0 ? -errno : r;
}

/* Returns true when path is a video capture node of the vivid driver. */
static bool is_vivid_capture(const char *path)
{
        struct v4l2_capability cap = {0};
        _cleanup_close_ int fd = open(path, O_RDWR | O_NONBLOCK);

        if (fd < 0 || xioctl(fd, VIDIOC_QUERYCAP, &cap) < 0)
                return false;
        return strcmp((const char *)cap.driver, "vivid") == 0 &&
               (cap.device_caps & V4L2_CAP_VIDEO_CAPTURE);
}

static size_t find_nodes(const char **paths, size_t max, glob_t *g)
{
        size_t n = 0;

        if (glob("/dev/video*", 0, NULL, g) != 0)
                return 0;
        for (size_t i = 0; i < g->gl_pathc && n < max; i++)
                if (is_vivid_capture(g->gl_pathv[i]))
                        paths[n++] = g->gl_pathv[i];
        return n;
}

/* Opens the node, sets 320x180 YUYV, maps N_BUFS buffers, queues them and starts streaming. */
static void node_start(struct node *n)
{
        struct v4l2_format fmt = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
        struct v4l2_requestbuffers req = {
                .count = N_BUFS, .type = V4L2_BUF_TYPE_VIDEO_CAPTURE, .memory = V4L2_MEMORY_MMAP};
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;

        n->fd = v4l2_open(n->path, O_RDWR | O_NONBLOCK);
        CHECK(n->fd >= 0);
        fmt.fmt.pix = (struct v4l2_pix_format){
                .width = 320, .height = 180, .pixelformat = V4L2_PIX_FMT_YUYV};
        CHECK_INT(xioctl(n->fd, VIDIOC_S_FMT, &fmt), 0);
        CHECK_INT(fmt.fmt.pix.width, 320);
        CHECK_INT(xioctl(n->fd, VIDIOC_REQBUFS, &req), 0);
        CHECK_INT(req.count, N_BUFS);
        for (unsigned i = 0; i < N_BUFS; i++) {
                struct v4l2_buffer b = {.index = i, .type = req.type, .memory = req.memory};

                CHECK_INT(xioctl(n->fd, VIDIOC_QUERYBUF, &b), 0);
                n->len[i] = b.length;
                n->buf[i] = v4l2_mmap(NULL, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, n->fd,
                                      b.m.offset);
                CHECK(n->buf[i] != MAP_FAILED);
                CHECK_INT(xioctl(n->fd, VIDIOC_QBUF, &b), 0);
        }
        CHECK_INT(xioctl(n->fd, VIDIOC_STREAMON, &type), 0);
}

/* Takes one ready frame, checks it against the node's previous one and queues it again. */
static void node_take(struct node *n)
{
        struct v4l2_buffer b = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE, .memory = V4L2_MEMORY_MMAP};
        unsigned long long us;

        if (xioctl(n->fd, VIDIOC_DQBUF, &b) == -EAGAIN)
                return;
        CHECK(b.index < N_BUFS);
        CHECK(b.bytesused > 0);
        us = (unsigned long long)b.timestamp.tv_sec * 1000000 + b.timestamp.tv_usec;
        if (n->frames > 0) {
                CHECK(us > n->last_us);
                CHECK(b.sequence > n->last_seq);
        }
        n->last_us = us;
        n->last_seq = b.sequence;
        n->frames++;
        CHECK_INT(xioctl(n->fd, VIDIOC_QBUF, &b), 0);
}

static void node_stop(struct node *n)
{
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;

        CHECK_INT(xioctl(n->fd, VIDIOC_STREAMOFF, &type), 0);
        for (unsigned i = 0; i < N_BUFS; i++)
                v4l2_munmap(n->buf[i], n->len[i]);
        v4l2_close(n->fd);
        printf("%s: %u frames, last sequence %u\n", n->path, n->frames, n->last_seq);
}

/* Polls every node until each delivered N_FRAMES frames; fails after 30 s. */
static void stream_all(struct node *nodes, size_t n)
{
        time_t deadline = time(NULL) + 30;
        struct pollfd pfd[MAX_NODES];
        bool done = false;

        while (!done) {
                CHECK(time(NULL) < deadline);
                for (size_t i = 0; i < n; i++)
                        pfd[i] = (struct pollfd){.fd = nodes[i].fd, .events = POLLIN};
                CHECK(poll(pfd, n, 1000) >= 0);
                done = true;
                for (size_t i = 0; i < n; i++) {
                        if (pfd[i].revents & POLLIN)
                                node_take(&nodes[i]);
                        done = done && nodes[i].frames >= N_FRAMES;
                }
        }
}

int main(int argc, char **argv)
{
        const char *paths[MAX_NODES];
        struct node nodes[MAX_NODES] = {0};
        glob_t g = {0};
        size_t n = argc > 1 ? (size_t)argc - 1 : find_nodes(paths, MAX_NODES, &g);

        CHECK(n >= 2 && n <= MAX_NODES);
        for (size_t i = 0; i < n; i++) {
                nodes[i].path = argc > 1 ? argv[i + 1] : paths[i];
                node_start(&nodes[i]);
        }
        stream_all(nodes, n);
        for (size_t i = 0; i < n; i++)
                node_stop(&nodes[i]);
        globfree(&g);
        return 0;
}
