"""Pilot participants: the experimenter's test runs and simulated participants, marked

participants.pilot: true for a participant who arrived through an entry link signed with the server's key
(study_server.pilots); such participants are kept out of the schedule's balance, the targets' freeze, the approval
list and the analysis, and `study reset` removes them. Everyone who arrived before is a real participant.

Revision ID: c5d1e8a2b946
Revises: b7e2c4d81f3a
Create Date: 2026-12-04 21:30:00.000000

"""
import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision = 'c5d1e8a2b946'
down_revision = 'b7e2c4d81f3a'
branch_labels = None
depends_on = None


def upgrade():
    with op.batch_alter_table('participants') as batch:
        # a literal default: SQLite adds the column in place (an expression would make batch mode copy the table)
        batch.add_column(sa.Column('pilot', sa.Boolean(), nullable=False, server_default='0'))


def downgrade():
    with op.batch_alter_table('participants', recreate='never') as batch:
        batch.drop_column('pilot')
