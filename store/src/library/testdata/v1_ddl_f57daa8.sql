-- The version-1 schema as commit f57daa8 wrote it, before outcome_columns! added a blank line.

CREATE TABLE scenarios (
    id          TEXT PRIMARY KEY NOT NULL,
    kind        TEXT NOT NULL CHECK (kind IN ('cut-in', 'emergency-braking', 'pedestrian-crossing',
                                              'sensor-occlusion', 'low-friction')),
    seed        INTEGER NOT NULL,
    params      TEXT NOT NULL,
    parent_id   TEXT REFERENCES scenarios(id),
    generation  INTEGER NOT NULL CHECK (generation >= 0),
    origin      TEXT NOT NULL CHECK (origin IN ('sampled', 'mutated', 'imported', 'regression')),
    created_seq INTEGER NOT NULL UNIQUE
) STRICT;
CREATE INDEX scenarios_by_parent ON scenarios(parent_id);
CREATE INDEX scenarios_by_kind ON scenarios(kind);

CREATE TABLE outcomes (
    seq                     INTEGER PRIMARY KEY,
    scenario_id             TEXT NOT NULL REFERENCES scenarios(id),
    policy                  TEXT NOT NULL CHECK (policy <> ''),
    collision               INTEGER NOT NULL CHECK (collision IN (0, 1)),
    offroad                 INTEGER NOT NULL CHECK (offroad IN (0, 1)),
    success                 INTEGER NOT NULL CHECK (success IN (0, 1)),
    route_completion        REAL NOT NULL,
    avg_speed_mps           REAL NOT NULL,
    steering_smoothness     REAL NOT NULL,
    longitudinal_smoothness REAL NOT NULL,
    min_ttc_s               REAL,
    min_distance_m          REAL NOT NULL,
    episode_risk_score      REAL NOT NULL,
    reward                  REAL NOT NULL,
    steps                   INTEGER NOT NULL CHECK (steps >= 0),
    risk_score              REAL NOT NULL CHECK (risk_score BETWEEN 0 AND 1),
    risk_ttc                REAL NOT NULL CHECK (risk_ttc BETWEEN 0 AND 1),
    risk_dist               REAL NOT NULL CHECK (risk_dist BETWEEN 0 AND 1),
    risk_lane               REAL NOT NULL CHECK (risk_lane BETWEEN 0 AND 1),
    risk_jerk               REAL NOT NULL CHECK (risk_jerk BETWEEN 0 AND 1),
    risk_collision          REAL NOT NULL CHECK (risk_collision BETWEEN 0 AND 1)
) STRICT;
CREATE INDEX outcomes_latest ON outcomes(scenario_id, policy, seq);

CREATE TABLE rejected (
    kind   TEXT NOT NULL,
    reason TEXT NOT NULL,
    count  INTEGER NOT NULL CHECK (count >= 0),
    PRIMARY KEY (kind, reason)
) STRICT;

CREATE TABLE regression (
    scenario_id TEXT PRIMARY KEY NOT NULL REFERENCES scenarios(id),
    reason      TEXT NOT NULL CHECK (reason IN ('collision', 'manual')),
    marked_seq  INTEGER NOT NULL
) STRICT;
