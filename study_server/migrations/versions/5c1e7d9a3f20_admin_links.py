"""One-time admin sign-in links; a participant's lists indexed by time

admin_links: the operator's way in that failed logins from an anonymous crowd cannot close
(``scenesuggest study admin-link``). lists: the index on participant_id becomes one on (participant_id,
created_at), which the list rate reads (the newest lists of a participant).

Revision ID: 5c1e7d9a3f20
Revises: 3b9d2c41e7a5
Create Date: 2026-12-04 03:00:00.000000

"""
import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision = '5c1e7d9a3f20'
down_revision = '3b9d2c41e7a5'
branch_labels = None
depends_on = None


def upgrade():
    op.create_table('admin_links',
                    sa.Column('id', sa.String(length=64), nullable=False),
                    sa.Column('created_at', sa.DateTime(), nullable=False),
                    sa.Column('expires_at', sa.DateTime(), nullable=False),
                    sa.Column('used_at', sa.DateTime(), nullable=True),
                    sa.PrimaryKeyConstraint('id'))
    op.drop_index('ix_lists_participant_id', table_name='lists')
    op.create_index('ix_lists_participant_created', 'lists', ['participant_id', 'created_at'], unique=False)


def downgrade():
    op.drop_index('ix_lists_participant_created', table_name='lists')
    op.create_index('ix_lists_participant_id', 'lists', ['participant_id'], unique=False)
    op.drop_table('admin_links')
