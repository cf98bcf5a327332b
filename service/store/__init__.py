"""The job store: SQLModel tables on SQLite (WAL) or any SQLAlchemy URL, with migrations."""
