"""AWS Deadline Cloud's own command line (``deadline bundle submit ...``) run with only its AWS
calls answered here: the queue (with job attachments), the queue's parameters (none) and the queue
role's session. Everything else is the client's code: it reads the bundle, decides which paths it
knows, asks or cancels (``--yes``), hashes the attachments and, with ``--save-debug-snapshot``,
writes what it would send to CreateJob and upload to S3 instead of sending it.

    python deadline_offline.py bundle submit BUNDLE --yes --farm-id ... --queue-id ... --save-debug-snapshot DIR
"""

import sys

import boto3
from deadline.client import api
from deadline.client.cli import main


class Deadline:
    """The Deadline Cloud API calls a snapshot of a submission makes."""

    def get_queue(self, farmId, queueId):  # noqa: N803 (the API's own names)
        return {"displayName": "Windgrass test queue", "farmId": farmId, "queueId": queueId,
                "jobAttachmentSettings": {"s3BucketName": "windgrass-test-attachments", "rootPrefix": "DeadlineCloud"}}


api.get_boto3_client = lambda service, config=None: Deadline()
api.get_queue_parameter_definitions = lambda **kw: []
api.get_queue_user_boto3_session = lambda *a, **kw: boto3.Session(
    aws_access_key_id="offline", aws_secret_access_key="offline", region_name="us-west-2")

if __name__ == "__main__":
    sys.argv[0] = "deadline"
    sys.exit(main())
