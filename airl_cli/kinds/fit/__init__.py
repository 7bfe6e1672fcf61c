"""The fit experiments: each job is an ``airl fit`` run whose scores per dynamics are its rows (thesis §7)."""
