"""A change proposal says how many robots saw it: per cell (``added_robots``,
``removed_robots``) and overall (``robots``); proposals made before say 0."""

from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("maps", "0007_membership_roles"),
    ]

    operations = [
        migrations.AddField(
            model_name="changeproposal",
            name="added_robots",
            field=models.JSONField(default=list),
        ),
        migrations.AddField(
            model_name="changeproposal",
            name="removed_robots",
            field=models.JSONField(default=list),
        ),
        migrations.AddField(
            model_name="changeproposal",
            name="robots",
            field=models.PositiveIntegerField(default=0),
        ),
    ]
