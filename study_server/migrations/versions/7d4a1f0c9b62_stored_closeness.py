"""A trial's whole closeness result, and the seq its replay check waits for, in columns of their own

trials.closeness: what :mod:`scenesuggest.contract.scoring` found when the trial was done (score, matched, missing,
extra, errors, the matched pairs), exported as stored so that a later change of the scoring code cannot make the
database and an export disagree. trials.replay_waits_for: the last seq the page logged before "done" while the replay
check waits for it (NULL: not waiting), which was prose in trials.replay; the pending checks of existing rows are
carried over.

Revision ID: 7d4a1f0c9b62
Revises: 5c1e7d9a3f20
Create Date: 2026-12-04 05:00:00.000000

"""
import re

import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision = '7d4a1f0c9b62'
down_revision = '5c1e7d9a3f20'
branch_labels = None
depends_on = None

_PENDING = re.compile(r"pending: events up to seq (\d+) not stored yet")


def upgrade():
    with op.batch_alter_table('trials') as batch:
        batch.add_column(sa.Column('closeness', sa.JSON(), nullable=True))
        batch.add_column(sa.Column('replay_waits_for', sa.Integer(), nullable=True))
    trials = sa.table('trials', sa.column('id', sa.Integer), sa.column('replay', sa.Text),
                      sa.column('replay_waits_for', sa.Integer))
    con = op.get_bind()
    waiting = con.execute(sa.select(trials.c.id, trials.c.replay).where(trials.c.replay.like('pending: %'))).all()
    for row in waiting:
        found = _PENDING.fullmatch(row.replay)
        if found:
            con.execute(trials.update().where(trials.c.id == row.id)
                        .values(replay_waits_for=int(found.group(1))))


def downgrade():
    # SQLite drops the columns in place (3.35+): the table keeps the CREATE text the migrations gave it, which a
    # restore compares
    with op.batch_alter_table('trials', recreate='never') as batch:
        batch.drop_column('replay_waits_for')
        batch.drop_column('closeness')
