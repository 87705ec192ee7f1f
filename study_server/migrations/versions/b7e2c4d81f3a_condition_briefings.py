"""A condition's instructions, shown before the trial where the interface changes

trials.briefing_shown_at: when the page with the condition's instructions was first shown before this trial (None:
none was due, or the trial was planned before briefings were shown); trials.briefed_at: when the participant
dismissed it and the trial began. The time between them is not trial time.

Revision ID: b7e2c4d81f3a
Revises: 9a3e5b7c1d24
Create Date: 2026-12-04 20:30:00.000000

"""
import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision = 'b7e2c4d81f3a'
down_revision = '9a3e5b7c1d24'
branch_labels = None
depends_on = None


def upgrade():
    with op.batch_alter_table('trials') as batch:
        batch.add_column(sa.Column('briefing_shown_at', sa.DateTime(), nullable=True))
        batch.add_column(sa.Column('briefed_at', sa.DateTime(), nullable=True))


def downgrade():
    with op.batch_alter_table('trials', recreate='never') as batch:
        batch.drop_column('briefed_at')
        batch.drop_column('briefing_shown_at')
