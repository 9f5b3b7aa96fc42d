-- The tables rosgate 0.1 (release 44, commit d15f2f1) made with create_all on sqlite: the schema a school's
-- database has before versions. Written by SQLAlchemy from that release's declarations; never edited.
CREATE TABLE ags_links (
	person VARCHAR(64) NOT NULL, 
	resource_link VARCHAR(255) NOT NULL, 
	issuer VARCHAR(255) NOT NULL, 
	client_id VARCHAR(255) NOT NULL, 
	subject VARCHAR(255) NOT NULL, 
	lineitem VARCHAR(1000) NOT NULL, 
	exercise VARCHAR(100), 
	scopes VARCHAR(1000) NOT NULL, 
	launched FLOAT NOT NULL, 
	PRIMARY KEY (person, resource_link)
);

CREATE TABLE ags_outbox (
	attempt_id VARCHAR(128) NOT NULL, 
	person VARCHAR(64) NOT NULL, 
	resource_link VARCHAR(255) NOT NULL, 
	score FLOAT NOT NULL, 
	comment VARCHAR(200), 
	created FLOAT NOT NULL, 
	tries INTEGER NOT NULL, 
	next_try FLOAT NOT NULL, 
	posted FLOAT, 
	last_error VARCHAR(500), 
	PRIMARY KEY (attempt_id)
);

CREATE TABLE bookings (
	id INTEGER NOT NULL, 
	station VARCHAR(100) NOT NULL, 
	person VARCHAR(200) NOT NULL, 
	name VARCHAR(200) NOT NULL, 
	start_at FLOAT NOT NULL, 
	end_at FLOAT NOT NULL, 
	created_at FLOAT NOT NULL, 
	PRIMARY KEY (id)
);

CREATE INDEX bookings_by_station ON bookings (station, start_at);

CREATE TABLE exercise_attempts (
	id INTEGER NOT NULL, 
	attempt VARCHAR(64) NOT NULL, 
	exercise VARCHAR(100) NOT NULL, 
	person VARCHAR(200) NOT NULL, 
	name VARCHAR(200) NOT NULL, 
	station VARCHAR(100) NOT NULL, 
	passed BOOLEAN NOT NULL, 
	score FLOAT NOT NULL, 
	why VARCHAR(20) NOT NULL, 
	started_at FLOAT NOT NULL, 
	ended_at FLOAT NOT NULL, 
	program TEXT NOT NULL, 
	recording VARCHAR(200), 
	PRIMARY KEY (id), 
	UNIQUE (attempt)
);

CREATE INDEX ix_exercise_attempts_exercise ON exercise_attempts (exercise);

CREATE INDEX ix_exercise_attempts_person ON exercise_attempts (person);

CREATE TABLE fleet_holds (
	kind VARCHAR(16) NOT NULL, 
	name VARCHAR(200) NOT NULL, 
	person VARCHAR(200) NOT NULL, 
	who VARCHAR(300) NOT NULL, 
	gateway VARCHAR(32) NOT NULL, 
	expires FLOAT NOT NULL, 
	PRIMARY KEY (kind, name)
);

CREATE TABLE history_minutes (
	series INTEGER NOT NULL, 
	t BIGINT NOT NULL, 
	n INTEGER NOT NULL, 
	vmin FLOAT NOT NULL, 
	vmean FLOAT NOT NULL, 
	vmax FLOAT NOT NULL
);

CREATE INDEX history_minutes_series_t ON history_minutes (series, t);

CREATE TABLE history_points (
	series INTEGER NOT NULL, 
	t BIGINT NOT NULL, 
	v FLOAT NOT NULL, 
	CONSTRAINT history_points_pk PRIMARY KEY (series, t)
)
 WITHOUT ROWID;

CREATE TABLE history_series (
	id INTEGER NOT NULL, 
	topic VARCHAR(255) NOT NULL, 
	field VARCHAR(255) NOT NULL, 
	PRIMARY KEY (id), 
	CONSTRAINT history_series_topic_field UNIQUE (topic, field)
);

CREATE TABLE lti_courses (
	url VARCHAR(1000) NOT NULL, 
	issuer VARCHAR(255) NOT NULL, 
	client_id VARCHAR(255) NOT NULL, 
	context VARCHAR(255) NOT NULL, 
	title VARCHAR(255) NOT NULL, 
	fetched FLOAT NOT NULL, 
	PRIMARY KEY (url)
);

CREATE TABLE lti_roster (
	issuer VARCHAR(255) NOT NULL, 
	context VARCHAR(255) NOT NULL, 
	person VARCHAR(64) NOT NULL, 
	name VARCHAR(100) NOT NULL, 
	roles VARCHAR(1000) NOT NULL, 
	status VARCHAR(20) NOT NULL, 
	fetched FLOAT NOT NULL, 
	PRIMARY KEY (issuer, context, person)
);

CREATE TABLE people (
	owner VARCHAR(100) NOT NULL, 
	name VARCHAR(200) NOT NULL, 
	role VARCHAR(16) NOT NULL, 
	kind VARCHAR(16) NOT NULL, 
	seen FLOAT NOT NULL, 
	PRIMARY KEY (owner)
);

CREATE TABLE run_output (
	run VARCHAR(16) NOT NULL, 
	seq INTEGER NOT NULL, 
	text TEXT NOT NULL, 
	CONSTRAINT run_output_pk PRIMARY KEY (run, seq)
);

CREATE TABLE runs (
	id VARCHAR(16) NOT NULL, 
	name VARCHAR(64) NOT NULL, 
	kind VARCHAR(32) NOT NULL, 
	owner VARCHAR(255), 
	who VARCHAR(255), 
	ns VARCHAR(255) NOT NULL, 
	started FLOAT NOT NULL, 
	ended FLOAT, 
	state VARCHAR(16) NOT NULL, 
	exit_code INTEGER, 
	reason TEXT, 
	source TEXT NOT NULL, 
	output_bytes BIGINT NOT NULL, 
	output_seen BIGINT NOT NULL, 
	cut BOOLEAN NOT NULL, 
	recording TEXT, 
	recording_bytes BIGINT NOT NULL, 
	PRIMARY KEY (id)
);

CREATE INDEX runs_owner_started ON runs (owner, started);

CREATE TABLE sessions (
	id_hash VARCHAR(64) NOT NULL, 
	name VARCHAR(200) NOT NULL, 
	role VARCHAR(16) NOT NULL, 
	kind VARCHAR(16) NOT NULL, 
	owner VARCHAR(100) NOT NULL, 
	created FLOAT NOT NULL, 
	expires FLOAT NOT NULL, 
	PRIMARY KEY (id_hash)
);
