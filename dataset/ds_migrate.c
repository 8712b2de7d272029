/* ds_migrate.c - brings the index of a dataset written by older software to the
 * current schema (see ds_internal.h, docs/dataset.md).
 *
 * DESIGN
 * Schema versions are PRAGMA user_version (mirrored in meta.schema_version for humans):
 *   1 (user_version 0): angles NOT NULL, no lamp bits, no names table.
 *   2: angles nullable (NULL = the rig has no axis of that role), lamp_bits added.
 *   3: the names table: each camera and lamp name with its number of captures, kept in
 *      the transaction of each row, so a summary never scans the captures.
 *   4: sessions: captures gain plan_seq (unique per session), kind, bracket, dark_id and
 *      flat_id (old rows: no plan item, kind 'image', bracket 0, no dark or flat); the
 *      sessions and plan tables are created empty (DS_V4_SQL, the same statements that
 *      create a new index).
 * An older index is brought to DS_SCHEMA_VERSION step by step in one BEGIN IMMEDIATE
 * transaction (SQLite's write lock: two openers cannot both migrate, and a failure
 * leaves the index as it was). */
#include <string.h>

#include "common/fileio.h"
#include "common/log.h"
#include "common/pose.h"
#include "common/yconf.h"
#include "ds_internal.h"

#define RIG_TEXT_MAX (1u << 20)

/* Schema 1 -> 2: SQLite cannot drop NOT NULL in place, so the table is copied. */
static const char migrate_v1_sql[] = DS_CAPTURES_TABLE(
        "captures_v2") "INSERT INTO captures_v2 (id, session, turntable_deg, light_arm_deg,"
                       " camera_arm_deg, camera, lamps, laser, exposure_us, gain, t_request_ns,"
                       " t_exposure_ns, t_stored_ns, file, sha256, width, height, pixfmt)"
                       " SELECT id, session, turntable_deg, light_arm_deg, camera_arm_deg,"
                       " camera, lamps, laser, exposure_us, gain, t_request_ns, t_exposure_ns,"
                       " t_stored_ns, file, sha256, width, height, pixfmt FROM captures;"
                       "DROP TABLE captures;"
                       "ALTER TABLE captures_v2 RENAME TO captures;" DS_CAPTURES_POSE_INDEX;

/* The lamp names of the rig file, in rig-file order (what lamp_bits indexes). */
struct rig_lamps {
        char name[GN_POSE_MAX_LAMPS][DS_NAME_MAX];
        size_t n;
};

/* Reads the lamp names of the dataset's rig.yaml; n is 0 without a usable one. */
static void read_rig_lamps(struct ds *d, struct rig_lamps *out)
{
        _cleanup_free_ void *text = NULL;
        struct yconf yc = {};
        struct fy_node *lamps;
        char err[256] = "";
        size_t len = 0;
        int n;

        out->n = 0;
        if (gn_read_file_at(d->dir_fd, DS_RIG, RIG_TEXT_MAX, &text, &len) < 0 ||
            yconf_open_string(&yc, DS_RIG, text, err, sizeof(err)) < 0) {
                yconf_close(&yc);
                return;
        }
        lamps = yconf_get(yconf_root(&yc), "lamps");
        n = lamps ? yconf_seq_len(&yc, lamps, "lamps") : 0;
        for (int i = 0; i < n && i < GN_POSE_MAX_LAMPS; i++) {
                if (yconf_str(&yc, yconf_seq_item(lamps, i), "name", out->name[i], DS_NAME_MAX) <=
                    0) {
                        out->n = 0; /* an unnamed lamp: the order cannot be trusted */
                        break;
                }
                out->n++;
        }
        yconf_close(&yc);
}

/* SQL function gn_lamp_bits(lamps): the bit set of a comma-separated list of lamp
 * names, by their index in the rig file (names it does not know count for nothing). */
static void lamp_bits(sqlite3_context *ctx, int argc, sqlite3_value **argv)
{
        const struct rig_lamps *rl = sqlite3_user_data(ctx);
        const char *list = (const char *)sqlite3_value_text(argv[0]);
        char copy[256], *save = NULL;
        uint32_t bits = 0;

        snprintf(copy, sizeof(copy), "%s", list ? list : "");
        for (char *t = strtok_r(copy, ",", &save); t; t = strtok_r(NULL, ",", &save))
                for (size_t i = 0; i < rl->n; i++)
                        if (strcmp(t, rl->name[i]) == 0)
                                bits |= UINT32_C(1) << i;
        sqlite3_result_int64(ctx, bits);
}

/* Fills lamp_bits of the rows of schema 1 from their lamp names and rig.yaml's order. */
static int fill_lamp_bits(struct ds *d)
{
        struct rig_lamps rl;
        int r, rc;

        read_rig_lamps(d, &rl);
        if (rl.n == 0) {
                log_notice("dataset '%s': no lamps in %s; old rows keep lamp_bits 0", d->path,
                           DS_RIG);
                return 0;
        }
        rc = sqlite3_create_function(d->db, "gn_lamp_bits", 1, SQLITE_UTF8 | SQLITE_DETERMINISTIC,
                                     &rl, lamp_bits, NULL, NULL);
        if (rc != SQLITE_OK)
                return ds_db_fail(d, rc, "Failed to register gn_lamp_bits");
        r = ds_db_exec(d, "UPDATE captures SET lamp_bits = gn_lamp_bits(lamps)");
        (void)sqlite3_create_function(d->db, "gn_lamp_bits", 1, SQLITE_UTF8, NULL, NULL, NULL,
                                      NULL);
        return r;
}

/* Schema 2 -> 3: the names table, counted from the rows there are. */
static int migrate_v2(struct ds *d)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL, *add = NULL;
        int r, rc = SQLITE_DONE;

        r = ds_db_exec(d, DS_NAMES_TABLE);
        if (r == 0)
                r = ds_db_prepare(d, DS_ADD_NAME_SQL, &add);
        if (r == 0)
                r = ds_db_prepare(d,
                                  "SELECT camera, lamps, count(*) FROM captures"
                                  " GROUP BY camera, lamps",
                                  &s);
        while (r == 0 && (rc = sqlite3_step(s)) == SQLITE_ROW) {
                int64_t n = sqlite3_column_int64(s, 2);

                r = ds_db_add_names(d, add, "camera", (const char *)sqlite3_column_text(s, 0), n);
                if (r == 0)
                        r = ds_db_add_names(d, add, "lamp", (const char *)sqlite3_column_text(s, 1),
                                            n);
        }
        if (r == 0 && rc != SQLITE_DONE)
                r = ds_db_fail(d, rc, "Failed to count names");
        return r;
}

/* Brings the index from user_version v to DS_SCHEMA_VERSION (caller's transaction). */
static int migrate_from(struct ds *d, int64_t v)
{
        char version[16];
        int r = 0;

        if (v == 0) {
                r = ds_meta_get(d, "schema_version", version, sizeof(version));
                if (r == 0 && strcmp(version, "1") != 0)
                        r = ds_fail(d, -EBADMSG, "unknown schema version %s", version);
                if (r == 0)
                        r = ds_db_exec(d, migrate_v1_sql);
                if (r == 0)
                        r = fill_lamp_bits(d);
        }
        if (r == 0 && v <= 2)
                r = migrate_v2(d);
        if (r == 0 && v <= 3)
                r = ds_db_exec(d, DS_V4_SQL);
        if (r == 0)
                r = ds_db_exec(d, "PRAGMA user_version = 4;"
                                  "UPDATE meta SET value = '4' WHERE key = 'schema_version';");
        return r;
}

int ds_db_upgrade(struct ds *d)
{
        int64_t v = 0;
        int r;

        r = ds_db_int64(d, "PRAGMA user_version", &v);
        if (r < 0 || v == DS_SCHEMA_VERSION)
                return r;
        if (v > DS_SCHEMA_VERSION || v == 1)
                return ds_fail(d, -EBADMSG, "unknown schema version %lld (newer software?)",
                               (long long)v);
        r = ds_db_exec(d, "BEGIN IMMEDIATE");
        if (r == 0)
                r = ds_db_int64(d, "PRAGMA user_version", &v); /* another opener may have won */
        if (r == 0 && v < DS_SCHEMA_VERSION) {
                log_notice("dataset '%s': migrating its index from schema %lld to %d", d->path,
                           (long long)(v == 0 ? 1 : v), DS_SCHEMA_VERSION);
                r = migrate_from(d, v);
        }
        if (r == 0)
                return ds_db_exec(d, "COMMIT");
        (void)sqlite3_exec(d->db, "ROLLBACK", NULL, NULL, NULL);
        return r;
}
