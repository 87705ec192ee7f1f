"""Studies: their files, read and validated; the studies a server runs; balanced schedules; new studies; what a
study needs prepared; a study's answers given offline."""
