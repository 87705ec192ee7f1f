"""Events keep one index on the participant: the unique (participant_id, seq)

The single-column index on events.participant_id repeated the leading column of the unique constraint
uq_event_seq, which answers every lookup by participant as well; each stored event paid for both.

Revision ID: 3b9d2c41e7a5
Revises: 845fa003e0d7
Create Date: 2026-12-02 09:10:00.000000

"""
from alembic import op

# revision identifiers, used by Alembic.
revision = '3b9d2c41e7a5'
down_revision = '845fa003e0d7'
branch_labels = None
depends_on = None


def upgrade():
    op.drop_index('ix_events_participant_id', table_name='events')


def downgrade():
    op.create_index('ix_events_participant_id', 'events', ['participant_id'], unique=False)
