"""The language each participant's pages speak

participants.language: chosen at arrival among the study's languages (its only one, or the one the browser prefers)
and kept for the session; exported with the participant. Participants who arrived before it was kept saw English.

Revision ID: 9a3e5b7c1d24
Revises: 7d4a1f0c9b62
Create Date: 2026-12-04 06:10:00.000000

"""
import sqlalchemy as sa
from alembic import op

# revision identifiers, used by Alembic.
revision = '9a3e5b7c1d24'
down_revision = '7d4a1f0c9b62'
branch_labels = None
depends_on = None


def upgrade():
    with op.batch_alter_table('participants') as batch:
        batch.add_column(sa.Column('language', sa.String(length=16), nullable=True))
    op.execute("UPDATE participants SET language = 'en'")


def downgrade():
    # SQLite drops the column in place (3.35+): the table keeps the CREATE text the migrations gave it
    with op.batch_alter_table('participants', recreate='never') as batch:
        batch.drop_column('language')
